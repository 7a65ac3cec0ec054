//! The `cadmm._cadmm` extension module: the Rust solver behind the `cadmm` Python package.
//! The pure-Python half (`cadmm/`) adds the exceptions, the status enum and FCLib I/O.

mod convert;
mod errors;
mod problem;
mod settings;
mod solver;

use pyo3::prelude::*;

#[pymodule]
fn _cadmm(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<problem::GlobalProblem>()?;
    m.add_class::<problem::LocalProblem>()?;
    m.add_class::<settings::Settings>()?;
    m.add_class::<solver::Solver>()?;
    m.add_class::<solver::Solution>()?;
    m.add_class::<solver::Stats>()?;
    m.add_function(wrap_pyfunction!(problem::error, m)?)?;
    Ok(())
}
