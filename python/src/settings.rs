//! Solver settings, each validated when it is set.

use crate::errors::OrRaise;
use cadmm::{LinearSolver, VariantChoice};
use pyo3::prelude::*;

/// Settings of a solve; every keyword is optional and checked when set
/// (`InvalidSettingError` names the bad one).
#[pyclass(module = "cadmm")]
#[derive(Clone)]
pub struct Settings {
    pub inner: cadmm::Settings,
    variant: String,
    linear_solver: String,
}

/// A count setting: a negative one is refused like any other bad value.
fn count(py: Python<'_>, name: &'static str, x: i64) -> PyResult<usize> {
    usize::try_from(x).map_err(|_| {
        let reason = format!("must not be negative, got {x}");
        crate::errors::to_py(py, cadmm::Error::InvalidSetting { name, reason })
    })
}

impl Settings {
    /// Takes `next` when it is valid; otherwise raises and keeps the current settings.
    fn take(&mut self, py: Python<'_>, next: cadmm::Settings) -> PyResult<()> {
        next.validate().or_raise(py)?;
        self.inner = next;
        Ok(())
    }
}

#[pymethods]
impl Settings {
    #[new]
    #[pyo3(signature = (*, tolerance=None, max_iterations=None, time_limit=None, variant=None,
                        linear_solver=None, threads=None))]
    fn new(
        py: Python<'_>,
        tolerance: Option<f64>,
        max_iterations: Option<i64>,
        time_limit: Option<f64>,
        variant: Option<String>,
        linear_solver: Option<String>,
        threads: Option<i64>,
    ) -> PyResult<Self> {
        let mut s = Self {
            inner: cadmm::Settings::default(),
            variant: "auto".into(),
            linear_solver: "auto".into(),
        };
        if let Some(x) = tolerance {
            s.set_tolerance(py, x)?;
        }
        if let Some(x) = max_iterations {
            s.set_max_iterations(py, x)?;
        }
        if time_limit.is_some() {
            s.set_time_limit(py, time_limit)?;
        }
        if let Some(x) = variant {
            s.set_variant(py, x)?;
        }
        if let Some(x) = linear_solver {
            s.set_linear_solver(py, x)?;
        }
        if let Some(x) = threads {
            s.set_threads(py, x)?;
        }
        Ok(s)
    }

    /// Target of the error measure (default 1e-8).
    #[getter]
    fn tolerance(&self) -> f64 {
        self.inner.tolerance
    }

    #[setter]
    fn set_tolerance(&mut self, py: Python<'_>, x: f64) -> PyResult<()> {
        let next = cadmm::Settings {
            tolerance: x,
            ..self.inner.clone()
        };
        self.take(py, next)
    }

    /// Iteration limit (default 100000).
    #[getter]
    fn max_iterations(&self) -> usize {
        self.inner.max_iterations
    }

    #[setter]
    fn set_max_iterations(&mut self, py: Python<'_>, x: i64) -> PyResult<()> {
        let max_iterations = count(py, "max_iterations", x)?;
        let next = cadmm::Settings {
            max_iterations,
            ..self.inner.clone()
        };
        self.take(py, next)
    }

    /// Wall-clock limit of one solve in seconds (default: none, `inf`; None also means
    /// none).
    #[getter]
    fn time_limit(&self) -> f64 {
        self.inner.time_limit
    }

    #[setter]
    fn set_time_limit(&mut self, py: Python<'_>, x: Option<f64>) -> PyResult<()> {
        let time_limit = x.unwrap_or(f64::INFINITY);
        let next = cadmm::Settings {
            time_limit,
            ..self.inner.clone()
        };
        self.take(py, next)
    }

    /// `"auto"` (default), `"newton"` or one of the twelve ADMM variants (`"cp-N"` ...
    /// `"vp-RR-Spectral"`).
    #[getter]
    fn variant(&self) -> &str {
        &self.variant
    }

    #[setter]
    fn set_variant(&mut self, py: Python<'_>, name: String) -> PyResult<()> {
        let variant = VariantChoice::from_name(&name).or_raise(py)?;
        self.take(
            py,
            cadmm::Settings {
                variant,
                ..self.inner.clone()
            },
        )?;
        self.variant = name;
        Ok(())
    }

    /// How the global form's linear systems are solved: `"auto"` (default), `"direct"` or
    /// `"iterative"`.
    #[getter]
    fn linear_solver(&self) -> &str {
        &self.linear_solver
    }

    #[setter]
    fn set_linear_solver(&mut self, py: Python<'_>, name: String) -> PyResult<()> {
        let linear_solver = LinearSolver::from_name(&name).or_raise(py)?;
        self.take(
            py,
            cadmm::Settings {
                linear_solver,
                ..self.inner.clone()
            },
        )?;
        self.linear_solver = name;
        Ok(())
    }

    /// Threads a solve may use (default 1): islands are solved side by side.
    #[getter]
    fn threads(&self) -> usize {
        self.inner.threads
    }

    #[setter]
    fn set_threads(&mut self, py: Python<'_>, x: i64) -> PyResult<()> {
        let threads = count(py, "threads", x)?;
        let next = cadmm::Settings {
            threads,
            ..self.inner.clone()
        };
        self.take(py, next)
    }

    fn __repr__(&self) -> String {
        format!(
            "Settings(tolerance={:e}, max_iterations={}, time_limit={}, variant='{}', \
             linear_solver='{}', threads={})",
            self.inner.tolerance,
            self.inner.max_iterations,
            self.inner.time_limit,
            self.variant,
            self.linear_solver,
            self.inner.threads
        )
    }
}
