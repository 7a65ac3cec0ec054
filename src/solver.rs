//! The public solver: a problem, its settings, the factorizations and the last iterate.

use crate::admm::{self, EngineSettings, EngineState, Splitting};
use crate::cone::{get3, project_dual_cone, set3};
use crate::contact::{initial_rho, GlobalSplitting, LocalSplitting};
use crate::error::{Error, Status};
use crate::problem::Problem;
use crate::settings::{Resolved, Settings};
use crate::stats::{Stats, TracePoint};
use std::time::Instant;

enum Form {
    Global(GlobalSplitting),
    Local(LocalSplitting),
}

impl Form {
    fn splitting(&mut self) -> &mut dyn Splitting {
        match self {
            Form::Global(g) => g,
            Form::Local(l) => l,
        }
    }
    fn refactorizations(&self) -> usize {
        match self {
            Form::Global(g) => g.refactorizations(),
            Form::Local(l) => l.refactorizations(),
        }
    }
}

/// A solution of either form. `v` and `lambda` are empty for a local problem.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Solution {
    /// Contact impulses (`3 nc`).
    pub r: Vec<f64>,
    /// Local relative velocities (`3 nc`).
    pub u: Vec<f64>,
    /// Generalized velocities (`n`, global form only).
    pub v: Vec<f64>,
    /// Joint multipliers (global form with joints only).
    pub lambda: Vec<f64>,
}

/// Solves one frictional contact problem, and its successors with the same pattern.
pub struct Solver {
    settings: Settings,
    resolved: Resolved,
    form: Form,
    rho0: f64,
    state: EngineState,
    warm: bool,
    stats: Stats,
    trace: Vec<TracePoint>,
}

impl Solver {
    /// Validates the settings, picks the first rho, and factorizes (symbolic analysis and
    /// the first numeric factorization).
    pub fn new(problem: Problem, settings: Settings) -> Result<Self, Error> {
        let t0 = Instant::now();
        settings.validate()?;
        let resolved = settings.resolved();
        let rho0 = initial_rho(resolved.initial_rho, &problem)?;
        let l = 3 * problem.n_contacts();
        let mut form = match problem {
            Problem::Global(g) => Form::Global(GlobalSplitting::new(g)?),
            Problem::Local(p) => Form::Local(LocalSplitting::new(p)?),
        };
        form.splitting().set_rho(rho0)?;
        let state = EngineState {
            y: vec![0.0; l],
            zeta: vec![0.0; l],
            ax: vec![0.0; l],
            rho: rho0,
        };
        let stats = Stats {
            setup_seconds: t0.elapsed().as_secs_f64(),
            rho: rho0,
            refactorizations: form.refactorizations(),
            ..Default::default()
        };
        Ok(Self {
            settings,
            resolved,
            form,
            rho0,
            state,
            warm: false,
            stats,
            trace: Vec::new(),
        })
    }

    /// The settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The variant, initial rho rule and Anderson memory actually used.
    pub fn resolved(&self) -> &Resolved {
        &self.resolved
    }

    /// Replaces the problem by one with the same sizes and sparsity patterns (the next time
    /// step of a simulation): numeric refactorization only.
    pub fn update(&mut self, problem: Problem) -> Result<(), Error> {
        let same_form = matches!(
            (&self.form, &problem),
            (Form::Global(_), Problem::Global(_)) | (Form::Local(_), Problem::Local(_))
        );
        if !same_form {
            return Err(Error::Unsupported(
                "update: the new problem is of the other form (global/local)".into(),
            ));
        }
        if problem.n_contacts() * 3 != self.state.y.len() {
            return Err(Error::Dimension {
                field: "n_contacts",
                expected: self.state.y.len() / 3,
                found: problem.n_contacts(),
            });
        }
        if problem.n_velocities() != self.n_velocities() {
            return Err(Error::Dimension {
                field: "n",
                expected: self.n_velocities(),
                found: problem.n_velocities(),
            });
        }
        match (&mut self.form, problem) {
            (Form::Global(g), Problem::Global(p)) => g.update(p)?,
            (Form::Local(l), Problem::Local(p)) => l.update(p)?,
            _ => unreachable!("the forms were compared above"),
        }
        self.form.splitting().set_rho(self.rho0)?;
        self.warm = false;
        Ok(())
    }

    fn n_velocities(&self) -> usize {
        match &self.form {
            Form::Global(g) => g.problem().n(),
            Form::Local(_) => 0,
        }
    }

    /// Starts the next solve from impulses `r` (and velocities `v`, global form).
    pub fn warm_start(&mut self, r: &[f64], v: Option<&[f64]>) -> Result<(), Error> {
        let l = self.state.y.len();
        if r.len() != l {
            return Err(Error::Dimension {
                field: "r",
                expected: l,
                found: r.len(),
            });
        }
        if let Some(index) = r.iter().position(|x| !x.is_finite()) {
            return Err(Error::InvalidValue {
                field: "r",
                index,
                reason: "not finite",
            });
        }
        let rho = self.rho0;
        match &mut self.form {
            Form::Global(g) => {
                let n = g.problem().n();
                for i in 0..l {
                    self.state.zeta[i] = -r[i] / rho;
                }
                self.state.y.fill(0.0);
                if let Some(v) = v {
                    if v.len() != n {
                        return Err(Error::Dimension {
                            field: "v",
                            expected: n,
                            found: v.len(),
                        });
                    }
                    if let Some(index) = v.iter().position(|x| !x.is_finite()) {
                        return Err(Error::InvalidValue {
                            field: "v",
                            index,
                            reason: "not finite",
                        });
                    }
                    // u~ = P_K*(H^T v + w + Phi(u)), the shift taken from the same u.
                    g.shift_from_velocity(v);
                    let mut ax = vec![0.0; l];
                    g.problem().h.mul_t_vec(1.0, v, 0.0, &mut ax);
                    let c = g.c();
                    for (i, &mu) in g.problem().mu.iter().enumerate() {
                        let a = get3(&ax, i);
                        let ci = get3(c, i);
                        set3(
                            &mut self.state.y,
                            i,
                            project_dual_cone([a[0] - ci[0], a[1] - ci[1], a[2] - ci[2]], mu),
                        );
                    }
                } else {
                    g.reset_shift();
                }
            }
            Form::Local(s) => {
                s.shift_from_impulse(r);
                // At a solution u~ = W r + q + Phi = -rho zeta.
                let mut u = vec![0.0; l];
                s.velocity(r, &mut u);
                for (i, &mu) in s.problem().mu.iter().enumerate() {
                    let ui = get3(&u, i);
                    let shift = mu * (ui[1] * ui[1] + ui[2] * ui[2]).sqrt();
                    set3(
                        &mut self.state.zeta,
                        i,
                        [-(ui[0] + shift) / rho, -ui[1] / rho, -ui[2] / rho],
                    );
                }
                self.state.y.copy_from_slice(r);
            }
        }
        self.state.rho = rho;
        self.warm = true;
        Ok(())
    }

    /// Runs ADMM. Without a preceding [`Solver::warm_start`], starts from zero.
    pub fn solve(&mut self) -> Result<Status, Error> {
        let t0 = Instant::now();
        if !self.warm {
            self.state.y.fill(0.0);
            self.state.zeta.fill(0.0);
            self.state.rho = self.rho0;
            match &mut self.form {
                Form::Global(g) => g.reset_shift(),
                Form::Local(l) => l.reset_shift(),
            }
        }
        self.warm = false;
        let set = EngineSettings {
            tolerance: self.settings.tolerance,
            max_iterations: self.settings.max_iterations,
            time_limit: self.settings.time_limit,
            variant: self.resolved.variant,
            anderson: self.resolved.anderson,
            anderson_interval: self.settings.anderson_interval,
            s_update: self.settings.s_update,
            eps_abs: 1e-6 * self.settings.tolerance.min(1e-3) / 1e-3,
            eps_rel: self.settings.tolerance,
            check_every: 5,
            trace: self.settings.trace,
            rho_range: 1e8,
            rho_change_factor: self.resolved.rho_change_factor,
        };
        let out = admm::run(self.form.splitting(), &mut self.state, &set, t0)?;
        let status = out.status.unwrap_or(Status::MaxIterations);
        if status == Status::NumericalError {
            // The splitting's velocity comes from the step that blew up: recompute it from
            // the last finite iterate, which the state holds.
            let mut ax = std::mem::take(&mut self.state.ax);
            self.form.splitting().set_rho(self.state.rho)?;
            self.form
                .splitting()
                .x_step(&self.state.y, &self.state.zeta, self.state.rho, &mut ax);
            self.state.ax = ax;
        }
        self.trace = out.trace;
        self.stats = Stats {
            status,
            iterations: out.iterations,
            error: out.error,
            primal_residual: out.primal,
            dual_residual: out.dual,
            rho: self.state.rho,
            refactorizations: self.form.refactorizations(),
            anderson_accepted: out.aa_accepted,
            anderson_rejected: out.aa_rejected,
            setup_seconds: self.stats.setup_seconds,
            solve_seconds: t0.elapsed().as_secs_f64(),
        };
        Ok(status)
    }

    /// The current solution (the last finite iterate).
    pub fn solution(&self) -> Solution {
        let l = self.state.y.len();
        match &self.form {
            Form::Global(g) => {
                let p = g.problem();
                let r: Vec<f64> = self
                    .state
                    .zeta
                    .iter()
                    .map(|z| -self.state.rho * z)
                    .collect();
                let v = g.v().to_vec();
                let mut u = p.w.clone();
                p.h.mul_t_vec(1.0, &v, 1.0, &mut u);
                Solution {
                    r,
                    u,
                    v,
                    lambda: g.lambda(),
                }
            }
            Form::Local(s) => {
                let r = self.state.y.clone();
                let mut u = vec![0.0; l];
                s.velocity(&r, &mut u);
                Solution {
                    r,
                    u,
                    v: Vec::new(),
                    lambda: Vec::new(),
                }
            }
        }
    }

    /// Statistics of the last solve.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Per-iteration trace of the last solve (empty unless `Settings::trace`).
    pub fn trace(&self) -> &[TracePoint] {
        &self.trace
    }
}
