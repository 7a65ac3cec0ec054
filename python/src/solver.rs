//! The solver: built once for a problem's pattern, solved with the GIL released, updated
//! between solves (the time steps of a simulation).

use crate::convert::{array, matrix_values, optional_vector, vector};
use crate::errors::OrRaise;
use crate::problem::{problem_of, GlobalProblem, LocalProblem};
use crate::settings::Settings;
use numpy::PyArray1;
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread;
use std::time::Duration;

/// How often a solve's calling thread runs Python's signal handlers (Ctrl-C).
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// Solves one frictional contact problem, and its successors (the same pattern through
/// `update_values`, any other through `rebuild`).
#[pyclass(module = "cadmm")]
pub struct Solver {
    /// Behind a lock: one solve at a time, and the GIL released while it runs.
    solver: Mutex<cadmm::Solver>,
    /// The problem it was built for, whose patterns new matrix values must keep.
    problem: Py<PyAny>,
    /// Set when a signal handler raises during a solve: the solve stops at its next
    /// iteration.
    interrupt: Arc<AtomicBool>,
}

impl Solver {
    /// The solver, or an error while another thread is using it.
    fn lock(&self) -> PyResult<MutexGuard<'_, cadmm::Solver>> {
        self.solver.try_lock().map_err(|_| {
            PyRuntimeError::new_err("the solver is in use by another thread (one call at a time)")
        })
    }
}

#[pymethods]
impl Solver {
    /// Validates, finds the contact islands and factorizes (symbolic analysis and the
    /// first numeric factorization), with the GIL released.
    #[new]
    #[pyo3(signature = (problem, settings=None))]
    fn new(
        py: Python<'_>,
        problem: &Bound<'_, PyAny>,
        settings: Option<PyRef<'_, Settings>>,
    ) -> PyResult<Self> {
        let built = problem_of(problem)?;
        let settings = settings.map(|s| s.inner.clone()).unwrap_or_default();
        let mut solver = py
            .detach(|| cadmm::Solver::new(built, settings))
            .or_raise(py)?;
        let interrupt = Arc::new(AtomicBool::new(false));
        solver.set_interrupt(interrupt.clone());
        Ok(Self {
            solver: Mutex::new(solver),
            problem: problem.clone().unbind(),
            interrupt,
        })
    }

    /// Runs the solve, with the GIL released, and returns its `cadmm.Status`. Starts from
    /// zero unless `warm_start` was called since the last solve or update. Ctrl-C (any
    /// signal handler that raises) stops it at its next iteration and raises, leaving the
    /// best iterate measured as the solution.
    fn solve(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let mut guard = self.lock()?;
        let solver: &mut cadmm::Solver = &mut guard;
        self.interrupt.store(false, Ordering::Relaxed);
        let (status, raised) = py.detach(|| solve_watching_signals(solver, &self.interrupt));
        if let Some(e) = raised {
            return Err(e);
        }
        status_of(py, status.or_raise(py)?)
    }

    /// The answer of the last solve (its best iterate when it did not solve; zeros before
    /// the first solve): copies of `r`, `u`, `v` and the joint multipliers.
    #[getter]
    fn solution(&self, py: Python<'_>) -> PyResult<Solution> {
        let solver = self.lock()?;
        let s = solver.solution();
        Ok(Solution {
            r: array(py, &s.r).unbind(),
            u: array(py, &s.u).unbind(),
            v: array(py, &s.v).unbind(),
            lambda_: array(py, &s.lambda).unbind(),
        })
    }

    /// Statistics of the last solve.
    #[getter]
    fn stats(&self, py: Python<'_>) -> PyResult<Stats> {
        let s = *self.lock()?.stats();
        Ok(Stats {
            status: status_of(py, s.status)?,
            iterations: s.iterations,
            error: s.error,
            primal_residual: s.primal_residual,
            dual_residual: s.dual_residual,
            rho: s.rho,
            refactorizations: s.refactorizations,
            newton_iterations: s.newton_iterations,
            islands: s.islands,
            setup_seconds: s.setup_seconds,
            solve_seconds: s.solve_seconds,
        })
    }

    /// Takes new values on the same sizes and sparsity patterns (the next time step):
    /// numeric refactorization only. Matrices come as matrices with the pattern the solver
    /// was built with, or as 1-D arrays of their values in compressed-column order. A
    /// refused update changes nothing. The next solve starts from zero unless
    /// `warm_start` follows.
    #[pyo3(signature = (*, M=None, H=None, G=None, f=None, w=None, b=None, mu=None, W=None, q=None, lo=None, hi=None, compliance=None, friction=None))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn update_values(
        &self,
        py: Python<'_>,
        M: Option<&Bound<'_, PyAny>>,
        H: Option<&Bound<'_, PyAny>>,
        G: Option<&Bound<'_, PyAny>>,
        f: Option<&Bound<'_, PyAny>>,
        w: Option<&Bound<'_, PyAny>>,
        b: Option<&Bound<'_, PyAny>>,
        mu: Option<&Bound<'_, PyAny>>,
        W: Option<&Bound<'_, PyAny>>,
        q: Option<&Bound<'_, PyAny>>,
        lo: Option<&Bound<'_, PyAny>>,
        hi: Option<&Bound<'_, PyAny>>,
        compliance: Option<&Bound<'_, PyAny>>,
        friction: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let built = self.problem.bind(py);
        let global = built.cast::<GlobalProblem>().ok().map(|g| &g.get().inner);
        let local = built.cast::<LocalProblem>().ok().map(|l| &l.get().inner);
        let joint_matrix = global.and_then(|g| g.joints.as_ref()).map(|j| &j.g);
        let values = |field, obj: Option<&Bound<'_, PyAny>>, pattern| {
            obj.filter(|o| !o.is_none())
                .map(|o| matrix_values(py, field, o, pattern))
                .transpose()
        };
        let m = values("M", M, global.map(|g| &g.m))?;
        let h = values("H", H, global.map(|g| &g.h))?;
        let g = values("G", G, joint_matrix)?;
        let delassus = values("W", W, local.map(|l| &l.w))?;
        let (f, w, b) = (
            optional_vector("f", f)?,
            optional_vector("w", w)?,
            optional_vector("b", b)?,
        );
        let (mu, q) = (optional_vector("mu", mu)?, optional_vector("q", q)?);
        let (lo, hi, compliance) = (
            optional_vector("lo", lo)?,
            optional_vector("hi", hi)?,
            optional_vector("compliance", compliance)?,
        );
        let friction = optional_vector("friction", friction)?;
        let new = cadmm::NewValues {
            m: m.as_deref(),
            h: h.as_deref(),
            g: g.as_deref(),
            f: f.as_deref(),
            w: w.as_deref(),
            b: b.as_deref(),
            lo: lo.as_deref(),
            hi: hi.as_deref(),
            compliance: compliance.as_deref(),
            friction: friction.as_deref(),
            mu: mu.as_deref(),
            delassus: delassus.as_deref(),
            q: q.as_deref(),
        };
        let mut guard = self.lock()?;
        let solver: &mut cadmm::Solver = &mut guard;
        py.detach(|| solver.update_values(&new)).or_raise(py)
    }

    /// Starts the next solve from impulses `r` (and velocities `v`, global form).
    #[pyo3(signature = (r, v=None))]
    fn warm_start(
        &self,
        py: Python<'_>,
        r: &Bound<'_, PyAny>,
        v: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let (r, v) = (vector("r", r)?, optional_vector("v", v)?);
        self.lock()?.warm_start(&r, v.as_deref()).or_raise(py)
    }

    /// Replaces the problem by one of any sizes and sparsity patterns (the next time step
    /// of a scene whose contacts changed), keeping the settings, with the GIL released: the
    /// solver becomes what `Solver(problem, settings)` builds, reusing the memory it holds.
    /// A refused problem changes nothing. The next solve starts from zero unless
    /// `warm_start` follows.
    fn rebuild(&mut self, py: Python<'_>, problem: &Bound<'_, PyAny>) -> PyResult<()> {
        let built = problem_of(problem)?;
        {
            let mut guard = self.lock()?;
            let solver: &mut cadmm::Solver = &mut guard;
            py.detach(|| solver.rebuild(&built)).or_raise(py)?;
        }
        self.problem = problem.clone().unbind();
        Ok(())
    }

    /// Changes the settings between solves: the tolerance, the iteration and time limits
    /// and the threads may change; any other change raises `InvalidSettingError`.
    fn update_settings(&self, py: Python<'_>, settings: PyRef<'_, Settings>) -> PyResult<()> {
        let next = settings.inner.clone();
        self.lock()?.update_settings(next).or_raise(py)
    }
}

/// Solves on a worker thread while this one, every [`SIGNAL_POLL`], runs Python's signal
/// handlers (which only the main thread can do); the exception of a handler that raises
/// sets `interrupt` and is handed back with the stopped solve's result.
fn solve_watching_signals(
    solver: &mut cadmm::Solver,
    interrupt: &AtomicBool,
) -> (Result<cadmm::Status, cadmm::Error>, Option<PyErr>) {
    thread::scope(|scope| {
        let caller = thread::current();
        let worker = scope.spawn(move || {
            let status = solver.solve();
            caller.unpark();
            status
        });
        let mut raised = None;
        while !worker.is_finished() {
            thread::park_timeout(SIGNAL_POLL);
            if raised.is_none() && !worker.is_finished() {
                raised = Python::attach(|py| py.check_signals()).err();
                if raised.is_some() {
                    interrupt.store(true, Ordering::Relaxed);
                }
            }
        }
        let status = worker
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (status, raised)
    })
}

/// The `cadmm.Status` of a solve's outcome.
fn status_of(py: Python<'_>, status: cadmm::Status) -> PyResult<Py<PyAny>> {
    let class = py.import("cadmm.status")?.getattr("Status")?;
    Ok(class.call1((status as i32,))?.unbind())
}

/// The answer of a solve (copies): impulses `r`, local velocities `u`, velocities `v`
/// (empty for a local problem) and joint multipliers `lambda_` (empty without joints).
#[pyclass(frozen, get_all, module = "cadmm")]
pub struct Solution {
    r: Py<PyArray1<f64>>,
    u: Py<PyArray1<f64>>,
    v: Py<PyArray1<f64>>,
    lambda_: Py<PyArray1<f64>>,
}

#[pymethods]
impl Solution {
    fn __repr__(&self, py: Python<'_>) -> String {
        let len = |a: &Py<PyArray1<f64>>| a.bind(py).len().unwrap_or(0);
        format!("Solution(len(r)={}, len(v)={})", len(&self.r), len(&self.v))
    }
}

/// Statistics of a solve.
#[pyclass(frozen, get_all, module = "cadmm")]
pub struct Stats {
    /// Outcome, a `cadmm.Status`.
    status: Py<PyAny>,
    /// ADMM iterations and Newton steps (of the island that needed the most).
    iterations: usize,
    /// Error measure of the answer handed back.
    error: f64,
    primal_residual: f64,
    dual_residual: f64,
    /// Final penalty.
    rho: f64,
    /// Numeric factorizations (setup and solve).
    refactorizations: usize,
    /// Of `iterations`, the semismooth Newton steps.
    newton_iterations: usize,
    /// Contact islands the problem was solved as.
    islands: usize,
    /// Seconds spent building the solver.
    setup_seconds: f64,
    /// Seconds spent in the last solve.
    solve_seconds: f64,
}

#[pymethods]
impl Stats {
    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "Stats(status={}, iterations={}, error={:e}, solve_seconds={:.3e})",
            self.status
                .bind(py)
                .str()
                .map_or_else(|_| "?".into(), |s| s.to_string()),
            self.iterations,
            self.error,
            self.solve_seconds
        )
    }
}
