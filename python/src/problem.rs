//! The two problem forms, immutable once built, and the error measure of any answer.

use crate::convert::{array, matrix, optional_vector, sparse, vector};
use crate::errors::{raise, OrRaise};
use numpy::PyArray1;
use pyo3::prelude::*;

/// A global problem `M v = H r + G lambda + f`, `u = H^T v + w`, with Coulomb cones of
/// coefficients `mu` (FCLib conventions, normal first) and joint rows
/// `G^T v + b + compliance * lambda`: equalities unless bounded, `lo <= lambda <= hi`, or
/// bounded by a contact's normal impulse, `|lambda_k| <= friction[k] r_n(friction_contact[k])`
/// (rolling and spinning friction; -1 for a row without a contact).
#[pyclass(frozen, module = "cadmm")]
pub struct GlobalProblem {
    pub inner: cadmm::GlobalProblem,
}

#[pymethods]
impl GlobalProblem {
    #[new]
    #[pyo3(signature = (M, H, f, w, mu, G=None, b=None, *, lo=None, hi=None, compliance=None, friction_contact=None, friction=None))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        M: &Bound<'_, PyAny>,
        H: &Bound<'_, PyAny>,
        f: &Bound<'_, PyAny>,
        w: &Bound<'_, PyAny>,
        mu: &Bound<'_, PyAny>,
        G: Option<&Bound<'_, PyAny>>,
        b: Option<&Bound<'_, PyAny>>,
        lo: Option<&Bound<'_, PyAny>>,
        hi: Option<&Bound<'_, PyAny>>,
        compliance: Option<&Bound<'_, PyAny>>,
        friction_contact: Option<Vec<i64>>,
        friction: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let problem = cadmm::GlobalProblem::new(
            matrix(py, "M", M)?,
            matrix(py, "H", H)?,
            vector("f", f)?,
            vector("w", w)?,
            vector("mu", mu)?,
        )
        .or_raise(py)?;
        let b = optional_vector("b", b)?;
        let inner = match (G.filter(|g| !g.is_none()), b) {
            (None, None) => problem,
            (None, Some(_)) => return Err(raise(py, "DimensionError", "b given without G")),
            (Some(g), b) => {
                let g = matrix(py, "G", g)?;
                let b = b.unwrap_or_else(|| vec![0.0; g.ncols()]);
                problem.with_joints(g, b).or_raise(py)?
            }
        };
        let p = inner.n_joints();
        let (lo, hi) = (optional_vector("lo", lo)?, optional_vector("hi", hi)?);
        let inner = match (lo, hi) {
            (None, None) => inner,
            (lo, hi) => inner
                .with_joint_bounds(
                    lo.unwrap_or_else(|| vec![f64::NEG_INFINITY; p]),
                    hi.unwrap_or_else(|| vec![f64::INFINITY; p]),
                )
                .or_raise(py)?,
        };
        let inner = match optional_vector("compliance", compliance)? {
            Some(c) => inner.with_joint_compliance(c).or_raise(py)?,
            None => inner,
        };
        let inner = match (friction_contact, optional_vector("friction", friction)?) {
            (None, None) => inner,
            (Some(contact), e) => {
                let e = e.unwrap_or_else(|| vec![0.0; contact.len()]);
                let mut rows = Vec::with_capacity(contact.len());
                for (k, &i) in contact.iter().enumerate() {
                    rows.push(match i {
                        -1 => None,
                        i if i >= 0 => Some(i as usize),
                        _ => {
                            let what =
                                format!("friction_contact[{k}] is {i}, neither -1 nor a contact");
                            return Err(raise(py, "InvalidValueError", &what));
                        }
                    });
                }
                inner.with_joint_friction(rows, e).or_raise(py)?
            }
            (None, Some(_)) => {
                return Err(raise(
                    py,
                    "DimensionError",
                    "friction given without friction_contact",
                ))
            }
        };
        Ok(Self { inner })
    }

    /// Number of velocities `n`.
    #[getter]
    fn n(&self) -> usize {
        self.inner.n()
    }

    /// Number of contacts.
    #[getter]
    fn n_contacts(&self) -> usize {
        self.inner.n_contacts()
    }

    /// Number of joint rows (columns of `G`; 0 without joints).
    #[getter]
    fn n_joints(&self) -> usize {
        self.inner.n_joints()
    }

    /// The mass matrix, as a `scipy.sparse.csc_array` (a copy).
    #[getter(M)]
    fn m<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        sparse(py, &self.inner.m)
    }

    /// The contact Jacobian transpose `H` (`n x 3 nc`), a copy.
    #[getter(H)]
    fn h<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        sparse(py, &self.inner.h)
    }

    /// The joint Jacobian transpose `G` (`n x p`), or None without joints.
    #[getter(G)]
    fn g<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.inner
            .joints
            .as_ref()
            .map(|j| sparse(py, &j.g))
            .transpose()
    }

    #[getter]
    fn f<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array(py, &self.inner.f)
    }

    #[getter]
    fn w<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array(py, &self.inner.w)
    }

    #[getter]
    fn mu<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array(py, &self.inner.mu)
    }

    /// The joints' right-hand side, or None without joints.
    #[getter]
    fn b<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.inner.joints.as_ref().map(|j| array(py, &j.b))
    }

    fn __repr__(&self) -> String {
        format!(
            "GlobalProblem(n={}, n_contacts={}, n_joints={})",
            self.n(),
            self.n_contacts(),
            self.n_joints()
        )
    }
}

/// A local problem `u = W r + q` with Coulomb cones of coefficients `mu`.
#[pyclass(frozen, module = "cadmm")]
pub struct LocalProblem {
    pub inner: cadmm::LocalProblem,
}

#[pymethods]
impl LocalProblem {
    #[new]
    #[allow(non_snake_case)]
    fn new(
        py: Python<'_>,
        W: &Bound<'_, PyAny>,
        q: &Bound<'_, PyAny>,
        mu: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let inner =
            cadmm::LocalProblem::new(matrix(py, "W", W)?, vector("q", q)?, vector("mu", mu)?)
                .or_raise(py)?;
        Ok(Self { inner })
    }

    /// Number of contacts.
    #[getter]
    fn n_contacts(&self) -> usize {
        self.inner.n_contacts()
    }

    /// The Delassus matrix `W` (`3 nc x 3 nc`), a copy.
    #[getter(W)]
    fn w<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        sparse(py, &self.inner.w)
    }

    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array(py, &self.inner.q)
    }

    #[getter]
    fn mu<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array(py, &self.inner.mu)
    }

    fn __repr__(&self) -> String {
        format!("LocalProblem(n_contacts={})", self.n_contacts())
    }
}

/// The problem a Python argument holds (a copy, for a solver to own).
pub fn problem_of(obj: &Bound<'_, PyAny>) -> PyResult<cadmm::Problem> {
    if let Ok(g) = obj.cast::<GlobalProblem>() {
        Ok(cadmm::Problem::Global(g.get().inner.clone()))
    } else if let Ok(l) = obj.cast::<LocalProblem>() {
        Ok(cadmm::Problem::Local(l.get().inner.clone()))
    } else {
        let msg = "expected a cadmm.GlobalProblem or a cadmm.LocalProblem";
        Err(pyo3::exceptions::PyTypeError::new_err(msg))
    }
}

/// Checks that `x` has `len` entries.
fn check_len(py: Python<'_>, field: &'static str, x: &[f64], len: usize) -> PyResult<()> {
    if x.len() == len {
        return Ok(());
    }
    let e = cadmm::Error::Dimension {
        field,
        expected: len,
        found: x.len(),
    };
    Err(crate::errors::to_py(py, e))
}

/// The error measure of an answer `(r, u, v)` to `problem` (docs/algorithms.md §3): `u` is
/// recomputed from `r` (local) or `v` (global), which the global form requires. The joint
/// multipliers `lambda_` are recomputed by least squares when not given (knowing nothing of
/// bounds: give them for a problem with bounded rows).
#[pyfunction]
#[pyo3(signature = (problem, r, u=None, v=None, lambda_=None))]
pub fn error(
    py: Python<'_>,
    problem: &Bound<'_, PyAny>,
    r: &Bound<'_, PyAny>,
    u: Option<&Bound<'_, PyAny>>,
    v: Option<&Bound<'_, PyAny>>,
    lambda_: Option<&Bound<'_, PyAny>>,
) -> PyResult<f64> {
    let _ = u;
    let r = vector("r", r)?;
    if let Ok(g) = problem.cast::<GlobalProblem>() {
        let g = &g.get().inner;
        check_len(py, "r", &r, 3 * g.n_contacts())?;
        let Some(v) = optional_vector("v", v)? else {
            return Err(raise(
                py,
                "DimensionError",
                "v is required for a global problem",
            ));
        };
        check_len(py, "v", &v, g.n())?;
        let lambda = optional_vector("lambda_", lambda_)?.unwrap_or_default();
        if !lambda.is_empty() {
            check_len(py, "lambda_", &lambda, g.n_joints())?;
        }
        Ok(py.detach(|| cadmm::measure::global_error(g, &r, &v, &lambda)))
    } else if let Ok(l) = problem.cast::<LocalProblem>() {
        let l = &l.get().inner;
        check_len(py, "r", &r, 3 * l.n_contacts())?;
        Ok(py.detach(|| cadmm::measure::local_error(l, &r)))
    } else {
        problem_of(problem).map(|_| f64::NAN)
    }
}
