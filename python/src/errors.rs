//! cadmm's errors as the Python exceptions of `cadmm.errors`, one class per C result code.

use pyo3::prelude::*;
use pyo3::types::PyType;

/// The exception class of `cadmm.errors` named `name`, raised with `message`.
pub fn raise(py: Python<'_>, name: &str, message: impl Into<String>) -> PyErr {
    let class = py
        .import("cadmm.errors")
        .and_then(|m| m.getattr(name))
        .and_then(|c| Ok(c.cast_into::<PyType>()?));
    match class {
        Ok(class) => PyErr::from_type(class, message.into()),
        Err(e) => e,
    }
}

/// The Python exception of a library error.
pub fn to_py(py: Python<'_>, e: cadmm::Error) -> PyErr {
    use cadmm::ErrorKind as K;
    let name = match e.kind() {
        K::Dimension => "DimensionError",
        K::InvalidCsc => "InvalidCscError",
        K::InvalidValue => "InvalidValueError",
        K::NotPositiveDefinite => "NotPositiveDefiniteError",
        K::Singular => "SingularError",
        K::InvalidSetting => "InvalidSettingError",
        K::PatternChanged => "PatternChangedError",
        K::OutOfMemory => "OutOfMemoryError",
        K::Unsupported => "UnsupportedError",
        K::Io => "IoError",
    };
    raise(py, name, e.to_string())
}

/// Turns a library result into a Python one.
pub trait OrRaise<T> {
    /// The value, or the library error as its Python exception.
    fn or_raise(self, py: Python<'_>) -> PyResult<T>;
}

impl<T> OrRaise<T> for Result<T, cadmm::Error> {
    fn or_raise(self, py: Python<'_>) -> PyResult<T> {
        self.map_err(|e| to_py(py, e))
    }
}
