//! Arguments in, arrays out: scipy.sparse matrices and array-likes become the library's
//! compressed-column matrices and vectors; results go back as numpy arrays and
//! `scipy.sparse.csc_array`s.

use crate::errors::{raise, OrRaise};
use cadmm::CscMatrix;
use numpy::{PyArray1, PyReadonlyArray1, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// `numpy.asarray(obj, dtype=dtype)`.
fn as_array<'py>(obj: &Bound<'py, PyAny>, dtype: &str) -> PyResult<Bound<'py, PyAny>> {
    let np = obj.py().import("numpy")?;
    np.getattr("asarray")?.call1((obj, np.getattr(dtype)?))
}

/// A vector argument: anything numpy reads as a 1-D float array.
pub fn vector(field: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    let a: PyReadonlyArrayDyn<'_, f64> = as_array(obj, "float64")?.extract()?;
    if a.ndim() != 1 {
        let msg = format!("{field} must be 1-D, got {} dimensions", a.ndim());
        return Err(raise(obj.py(), "DimensionError", msg));
    }
    Ok(a.as_array().iter().copied().collect())
}

/// An optional vector argument.
pub fn optional_vector(field: &str, obj: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Vec<f64>>> {
    obj.filter(|o| !o.is_none())
        .map(|o| vector(field, o))
        .transpose()
}

/// The compressed-column arrays of a matrix argument, in canonical order (columns sorted,
/// no duplicates): the order in which [`CscMatrix::set_values`] later takes new values.
pub struct CscParts {
    pub nrows: usize,
    pub ncols: usize,
    pub colptr: Vec<usize>,
    pub rowind: Vec<usize>,
    pub values: Vec<f64>,
}

impl CscParts {
    /// A scipy.sparse matrix or array in any format (duplicates summed, entries sorted, on
    /// a copy), or anything numpy reads as a 2-D float array (its non-zero entries).
    pub fn of(field: &str, obj: &Bound<'_, PyAny>) -> PyResult<Self> {
        if obj.hasattr("tocsc")? {
            Self::of_sparse(obj)
        } else {
            Self::of_dense(field, obj)
        }
    }

    fn of_sparse(obj: &Bound<'_, PyAny>) -> PyResult<Self> {
        let a = obj.call_method0("tocsc")?.call_method0("copy")?;
        a.call_method0("sum_duplicates")?; // sorts the row indices too
        let (nrows, ncols) = a.getattr("shape")?.extract()?;
        let index = |name| -> PyResult<Vec<usize>> {
            let x: PyReadonlyArray1<'_, i64> = as_array(&a.getattr(name)?, "int64")?.extract()?;
            Ok(x.as_array().iter().map(|&k| k as usize).collect())
        };
        let data: PyReadonlyArray1<'_, f64> =
            as_array(&a.getattr("data")?, "float64")?.extract()?;
        Ok(Self {
            nrows,
            ncols,
            colptr: index("indptr")?,
            rowind: index("indices")?,
            values: data.as_array().to_vec(),
        })
    }

    fn of_dense(field: &str, obj: &Bound<'_, PyAny>) -> PyResult<Self> {
        let a: PyReadonlyArrayDyn<'_, f64> = as_array(obj, "float64")?.extract()?;
        if a.ndim() != 2 {
            let msg = format!(
                "{field} must be a 2-D array or a scipy.sparse matrix, got {} dimensions",
                a.ndim()
            );
            return Err(raise(obj.py(), "DimensionError", msg));
        }
        let a = a.as_array();
        let (nrows, ncols) = (a.shape()[0], a.shape()[1]);
        let mut parts = Self {
            nrows,
            ncols,
            colptr: Vec::with_capacity(ncols + 1),
            rowind: Vec::new(),
            values: Vec::new(),
        };
        parts.colptr.push(0);
        for j in 0..ncols {
            for i in 0..nrows {
                let x = a[[i, j]];
                if x != 0.0 {
                    parts.rowind.push(i);
                    parts.values.push(x);
                }
            }
            parts.colptr.push(parts.rowind.len());
        }
        Ok(parts)
    }

    /// The validated matrix.
    pub fn into_matrix(self, py: Python<'_>, field: &'static str) -> PyResult<CscMatrix> {
        CscMatrix::new(
            field,
            self.nrows,
            self.ncols,
            self.colptr,
            self.rowind,
            self.values,
        )
        .or_raise(py)
    }

    /// The values, when the pattern is `m`'s; otherwise `PatternChangedError`.
    pub fn values_on(
        self,
        py: Python<'_>,
        field: &'static str,
        m: &CscMatrix,
    ) -> PyResult<Vec<f64>> {
        let same = (self.nrows, self.ncols) == (m.nrows(), m.ncols())
            && self.colptr == m.colptr()
            && self.rowind == m.rowind();
        if !same {
            return Err(crate::errors::to_py(
                py,
                cadmm::Error::PatternChanged { field },
            ));
        }
        Ok(self.values)
    }
}

/// A matrix argument as a validated library matrix.
pub fn matrix(py: Python<'_>, field: &'static str, obj: &Bound<'_, PyAny>) -> PyResult<CscMatrix> {
    CscParts::of(field, obj)?.into_matrix(py, field)
}

/// A numpy copy of `x`.
pub fn array<'py>(py: Python<'py>, x: &[f64]) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, x)
}

/// A `scipy.sparse.csc_array` copy of `m`.
pub fn sparse<'py>(py: Python<'py>, m: &CscMatrix) -> PyResult<Bound<'py, PyAny>> {
    let indices = |x: &[usize]| PyArray1::from_iter(py, x.iter().map(|&k| k as i64));
    let arrays = (
        array(py, m.values()),
        indices(m.rowind()),
        indices(m.colptr()),
    );
    let csc = py.import("scipy.sparse")?.getattr("csc_array")?;
    let kwargs = pyo3::types::PyDict::new(py);
    kwargs.set_item("shape", (m.nrows(), m.ncols()))?;
    csc.call((arrays,), Some(&kwargs))
}

/// New values of a matrix a solver was built with: a matrix (sparse or 2-D) with the same
/// pattern, or a 1-D array of values in the order of `pattern`'s compressed columns (that
/// of `problem.M.data`, for instance). Without a pattern (a field of the other form, or `G`
/// on a problem without joints) the values go on as given, for the library to refuse.
pub fn matrix_values(
    py: Python<'_>,
    field: &'static str,
    obj: &Bound<'_, PyAny>,
    pattern: Option<&CscMatrix>,
) -> PyResult<Vec<f64>> {
    let ndim: usize = py
        .import("numpy")?
        .getattr("ndim")?
        .call1((obj,))?
        .extract()?;
    match pattern {
        Some(m) if obj.hasattr("tocsc")? || ndim == 2 => {
            CscParts::of(field, obj)?.values_on(py, field, m)
        }
        _ => vector(field, obj),
    }
}
