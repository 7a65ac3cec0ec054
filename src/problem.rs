//! Frictional contact problems in FCLib conventions (normal component first).
//!
//! Global form: `M v = H r + G lambda + f`, `u = H^T v + w`, and per joint row
//! `lo <= lambda <= hi` against `G^T v + b + c lambda` (an equality, `= 0`, when the bounds
//! are infinite). Local form: `u = W r + q`. Both with `K*_mu ∋ u + Phi(u) ⊥ r ∈ K_mu` per
//! contact.

use crate::csc::CscMatrix;
use crate::types::Error;

/// Joint rows of a global problem: column `k` of `G` with its multiplier `lambda_k`, its
/// velocity `y_k = G_k^T v + b_k + c_k lambda_k` (`c` the compliance) and its bounds
/// `lo_k <= lambda_k <= hi_k`. A row whose bounds are both infinite (the default) is an
/// equality, `y_k = 0` (a bilateral joint); a bounded row holds `y_k = 0` while its
/// multiplier is inside its bounds and `y_k >= 0` at `lo_k`, `y_k <= 0` at `hi_k` (a
/// limit is `[0, inf)`, a motor or dry joint friction `[-F h, F h]` with `b` minus the
/// target velocity). A row may instead take its bounds from a contact: `[-e r_n, e r_n]`
/// with `r_n` the contact's normal impulse and `e` the row's coefficient (rolling and
/// spinning friction, docs/algorithms.md §1.4).
#[derive(Debug, PartialEq)]
pub struct Joints {
    /// `n x p` joint Jacobian transpose.
    pub g: CscMatrix,
    /// Length-`p` constant term.
    pub b: Vec<f64>,
    /// Length-`p` lower bounds of the multipliers (`-inf` for none).
    pub lo: Vec<f64>,
    /// Length-`p` upper bounds of the multipliers (`+inf` for none).
    pub hi: Vec<f64>,
    /// Length-`p` compliances `c >= 0` (velocity per unit impulse; 0 for a rigid row).
    pub compliance: Vec<f64>,
    /// Length-`p` contact whose normal impulse bounds each row (`None` for the rows whose
    /// bounds are `lo` and `hi` alone): row `k` with `Some(i)` holds `|lambda_k| <= e_k
    /// r_n(i)` as well as `lo_k <= lambda_k <= hi_k` (which must then hold zero).
    pub friction_contact: Vec<Option<usize>>,
    /// Length-`p` coefficients `e_k >= 0` of those rows (0 on the others): a length for a
    /// torque row (rolling resistance per unit normal impulse), a ratio for a force row.
    pub friction: Vec<f64>,
}

impl Joints {
    /// No rows on the velocities of `g` (which has no column).
    fn none(g: CscMatrix) -> Self {
        Joints {
            g,
            b: Vec::new(),
            lo: Vec::new(),
            hi: Vec::new(),
            compliance: Vec::new(),
            friction_contact: Vec::new(),
            friction: Vec::new(),
        }
    }

    /// Whether row `k` has a finite bound or a contact's (it is then an inequality, not an
    /// equality).
    pub fn is_bounded(&self, k: usize) -> bool {
        has_bound(self.lo[k], self.hi[k]) || self.friction_contact[k].is_some()
    }

    /// Row `k`'s bounds at the contact impulses `r` (normal first, 3 per contact): `lo_k`
    /// and `hi_k`, and for a row bounded by a contact their intersection with `-+ e_k r_n`
    /// (a negative `r_n`, which only an iterate can have, counts as zero).
    #[inline]
    pub fn bounds(&self, k: usize, r: &[f64]) -> (f64, f64) {
        let (lo, hi) = (self.lo[k], self.hi[k]);
        match self.friction_contact[k] {
            Some(i) => contact_bounds(lo, hi, self.friction[k], r[3 * i]),
            None => (lo, hi),
        }
    }

    /// Whether any row takes its bounds from a contact's normal impulse.
    pub fn has_contact_bounds(&self) -> bool {
        self.friction_contact.iter().any(Option::is_some)
    }

    /// Row `k`'s velocity `y = gv + b_k + c_k lambda` at `gv = G_k^T v`: the one definition
    /// the measure, Newton and the sweeps share. Without compliance it is `gv + b_k` bit for
    /// bit, the equality's residual as it always was.
    #[inline]
    pub fn row_velocity(&self, k: usize, gv: f64, lambda: f64) -> f64 {
        let c = self.compliance[k];
        if c == 0.0 {
            gv + self.b[k]
        } else {
            gv + self.b[k] + c * lambda
        }
    }

    /// Whether row `k` is bounded in both `self` and `other` or in neither.
    fn same_bounded_rows(&self, other: &Joints) -> bool {
        self.b.len() == other.b.len()
            && self.friction_contact == other.friction_contact
            && (0..self.b.len()).all(|k| self.is_bounded(k) == other.is_bounded(k))
    }

    /// The rows with a finite bound, in order.
    pub fn bounded_rows(&self) -> Vec<usize> {
        (0..self.b.len()).filter(|&k| self.is_bounded(k)).collect()
    }

    /// Whether any row has a bound or a compliance (what the FCLib format cannot hold).
    pub fn beyond_equalities(&self) -> bool {
        (0..self.b.len()).any(|k| self.is_bounded(k) || self.compliance[k] != 0.0)
    }

    /// Checks the joint fields of an update: sizes, values, and the same rows bounded.
    fn check_values(&self, v: &NewValues) -> Result<(), Error> {
        let p = self.b.len();
        if let Some(g) = v.g {
            self.g.check_values("G", g)?;
        }
        if let Some(b) = v.b {
            check_len("b", b, p)?;
        }
        if let Some(c) = v.compliance {
            check_compliance(c, p)?;
        }
        if let Some(e) = v.friction {
            check_friction(&self.friction_contact, e, p)?;
        }
        if v.lo.is_none() && v.hi.is_none() {
            return Ok(());
        }
        let (lo, hi) = (v.lo.unwrap_or(&self.lo), v.hi.unwrap_or(&self.hi));
        check_bounds(lo, hi, p)?;
        check_contact_rows(&self.friction_contact, lo, hi)?;
        let contact = |k: usize| self.friction_contact[k].is_some();
        match (0..p).all(|k| (has_bound(lo[k], hi[k]) || contact(k)) == self.is_bounded(k)) {
            true => Ok(()),
            false => Err(Error::PatternChanged {
                field: "joint bounds (which rows are bounded)",
            }),
        }
    }

    /// Checks the sizes and values of the rows' fields for `p` rows.
    fn validate(&self, n: usize) -> Result<(), Error> {
        let p = self.g.ncols();
        check_shape("G", &self.g, n, p)?;
        check_len("b", &self.b, p)?;
        check_bounds(&self.lo, &self.hi, p)?;
        check_compliance(&self.compliance, p)?;
        check_friction(&self.friction_contact, &self.friction, p)?;
        check_contact_rows(&self.friction_contact, &self.lo, &self.hi)?;
        // A row bounded by a contact acts on the bodies of its contact.
        match (0..p).find(|&k| self.friction_contact[k].is_some() && self.g.col(k).next().is_none())
        {
            Some(index) => Err(Error::InvalidValue {
                field: "G",
                index,
                reason: "a row bounded by a contact's normal impulse has no entry",
            }),
            None => Ok(()),
        }
    }
}

/// Own bounds of the rows bounded by contacts: they hold zero (`lo <= 0 <= hi`), as the
/// contact's `-+ e r_n` does, so that the two always intersect.
fn check_contact_rows(contact: &[Option<usize>], lo: &[f64], hi: &[f64]) -> Result<(), Error> {
    let wrong = |k: usize| contact[k].is_some() && (lo[k] > 0.0 || hi[k] < 0.0);
    match (0..contact.len()).find(|&k| wrong(k)) {
        Some(index) => Err(Error::InvalidValue {
            field: if lo[index] > 0.0 { "lo" } else { "hi" },
            index,
            reason: "the bounds of a row bounded by a contact's normal impulse exclude zero",
        }),
        None => Ok(()),
    }
}

/// Coefficients of `p` joint rows bounded by contacts: finite and non-negative, and zero
/// on the rows without a contact (a coefficient there would be silently ignored).
fn check_friction(contact: &[Option<usize>], e: &[f64], p: usize) -> Result<(), Error> {
    check_len("friction", e, p)?;
    for (k, (&x, c)) in e.iter().zip(contact).enumerate() {
        let reason = if x < 0.0 {
            "coefficient is negative"
        } else if x != 0.0 && c.is_none() {
            "coefficient on a row without a contact"
        } else {
            continue;
        };
        return Err(Error::InvalidValue {
            field: "friction",
            index: k,
            reason,
        });
    }
    Ok(())
}

/// The bounds `[lo, hi]` of a row bounded by a contact of normal impulse `rn` with the
/// coefficient `e`: intersected with `-+ e rn` (a negative `rn`, which only an iterate can
/// have, counts as zero). The one rule the measure, the sweeps and the splitting share.
#[inline]
pub(crate) fn contact_bounds(lo: f64, hi: f64, e: f64, rn: f64) -> (f64, f64) {
    let t = e * rn.max(0.0);
    (lo.max(-t), hi.min(t))
}

/// Whether the bounds `[lo, hi]` hold a finite one (the row is then an inequality).
fn has_bound(lo: f64, hi: f64) -> bool {
    lo > f64::NEG_INFINITY || hi < f64::INFINITY
}

/// Bounds of `p` joint rows: `lo <= hi`, neither NaN, `lo < +inf` and `hi > -inf`.
fn check_bounds(lo: &[f64], hi: &[f64], p: usize) -> Result<(), Error> {
    for (field, x) in [("lo", lo), ("hi", hi)] {
        if x.len() != p {
            return Err(Error::Dimension {
                field,
                expected: p,
                found: x.len(),
            });
        }
    }
    for k in 0..p {
        let reason = if lo[k].is_nan() || hi[k].is_nan() {
            "bound is NaN"
        } else if lo[k] == f64::INFINITY {
            "lower bound is +inf"
        } else if hi[k] == f64::NEG_INFINITY {
            "upper bound is -inf"
        } else if lo[k] > hi[k] {
            "lower bound above upper bound"
        } else {
            continue;
        };
        let field = if lo[k].is_nan() || lo[k] == f64::INFINITY {
            "lo"
        } else {
            "hi"
        };
        return Err(Error::InvalidValue {
            field,
            index: k,
            reason,
        });
    }
    Ok(())
}

/// Compliances of `p` joint rows: finite and non-negative.
fn check_compliance(c: &[f64], p: usize) -> Result<(), Error> {
    check_len("compliance", c, p)?;
    match c.iter().position(|&x| x < 0.0) {
        Some(index) => Err(Error::InvalidValue {
            field: "compliance",
            index,
            reason: "compliance is negative",
        }),
        None => Ok(()),
    }
}

/// Global (velocity) form: mass matrix, contact Jacobian transpose and data.
#[derive(Debug, PartialEq)]
pub struct GlobalProblem {
    /// `n x n` symmetric positive definite mass matrix, both triangles stored.
    pub m: CscMatrix,
    /// `n x 3nc` matrix mapping contact impulses to generalized forces.
    pub h: CscMatrix,
    /// Length-`n` free forces.
    pub f: Vec<f64>,
    /// Length-`3nc` free local velocity.
    pub w: Vec<f64>,
    /// Length-`nc` friction coefficients.
    pub mu: Vec<f64>,
    /// Optional bilateral constraints.
    pub joints: Option<Joints>,
}

impl Clone for Joints {
    fn clone(&self) -> Self {
        Self {
            g: self.g.clone(),
            b: self.b.clone(),
            lo: self.lo.clone(),
            hi: self.hi.clone(),
            compliance: self.compliance.clone(),
            friction_contact: self.friction_contact.clone(),
            friction: self.friction.clone(),
        }
    }

    /// Reuses the arrays' memory (a solver rebuilt for each step's problem).
    fn clone_from(&mut self, source: &Self) {
        let Self {
            g,
            b,
            lo,
            hi,
            compliance,
            friction_contact,
            friction,
        } = self;
        g.clone_from(&source.g);
        b.clone_from(&source.b);
        lo.clone_from(&source.lo);
        hi.clone_from(&source.hi);
        compliance.clone_from(&source.compliance);
        friction_contact.clone_from(&source.friction_contact);
        friction.clone_from(&source.friction);
    }
}

impl Clone for GlobalProblem {
    fn clone(&self) -> Self {
        Self {
            m: self.m.clone(),
            h: self.h.clone(),
            f: self.f.clone(),
            w: self.w.clone(),
            mu: self.mu.clone(),
            joints: self.joints.clone(),
        }
    }

    /// Reuses the arrays' memory (a solver rebuilt for each step's problem).
    fn clone_from(&mut self, source: &Self) {
        let Self {
            m,
            h,
            f,
            w,
            mu,
            joints,
        } = self;
        m.clone_from(&source.m);
        h.clone_from(&source.h);
        f.clone_from(&source.f);
        w.clone_from(&source.w);
        mu.clone_from(&source.mu);
        joints.clone_from(&source.joints);
    }
}

/// Local (Delassus) form: `u = W r + q`.
#[derive(Debug, Clone, PartialEq)]
pub struct LocalProblem {
    /// `3nc x 3nc` Delassus matrix, full storage, possibly non-symmetric.
    pub w: CscMatrix,
    /// Length-`3nc` free velocity.
    pub q: Vec<f64>,
    /// Length-`nc` friction coefficients.
    pub mu: Vec<f64>,
}

/// Either form of the problem.
#[derive(Debug, Clone, PartialEq)]
pub enum Problem {
    /// Global form.
    Global(GlobalProblem),
    /// Local form.
    Local(LocalProblem),
}

/// The sizes an update must keep, `[velocities, contacts]`: the first that differs, as a
/// dimension error (`n`, then `n_contacts`).
pub(crate) fn check_same_sizes(expected: [usize; 2], found: [usize; 2]) -> Result<(), Error> {
    for (field, expected, found) in [
        ("n", expected[0], found[0]),
        ("n_contacts", expected[1], found[1]),
    ] {
        if expected != found {
            return Err(Error::Dimension {
                field,
                expected,
                found,
            });
        }
    }
    Ok(())
}

pub(crate) fn check_len(field: &'static str, v: &[f64], expected: usize) -> Result<(), Error> {
    if v.len() != expected {
        return Err(Error::Dimension {
            field,
            expected,
            found: v.len(),
        });
    }
    check_finite(field, v)
}

fn check_finite(field: &'static str, v: &[f64]) -> Result<(), Error> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(index) => Err(Error::InvalidValue {
            field,
            index,
            reason: "not finite",
        }),
        None => Ok(()),
    }
}

pub(crate) fn check_mu(mu: &[f64], nc: usize) -> Result<(), Error> {
    check_len("mu", mu, nc)?;
    match mu.iter().position(|&x| x < 0.0) {
        Some(index) => Err(Error::InvalidValue {
            field: "mu",
            index,
            reason: "friction coefficient is negative",
        }),
        None => Ok(()),
    }
}

fn check_shape(
    field: &'static str,
    a: &CscMatrix,
    nrows: usize,
    ncols: usize,
) -> Result<(), Error> {
    if a.nrows() != nrows {
        return Err(Error::Dimension {
            field,
            expected: nrows,
            found: a.nrows(),
        });
    }
    if a.ncols() != ncols {
        return Err(Error::Dimension {
            field,
            expected: ncols,
            found: a.ncols(),
        });
    }
    Ok(())
}

/// The number of contacts, from the columns of `a` (H or W), three per contact, so that a
/// vector of the wrong length (`mu`, `w`, `q`) is named rather than the matrix. A column
/// count that is not a multiple of 3 is the matrix's error (`3 * mu_len` expected).
fn contacts(field: &'static str, a: &CscMatrix, mu_len: usize) -> Result<usize, Error> {
    if a.ncols() % 3 != 0 {
        return Err(Error::Dimension {
            field,
            expected: mu_len.saturating_mul(3),
            found: a.ncols(),
        });
    }
    Ok(a.ncols() / 3)
}

impl GlobalProblem {
    /// Validates and builds a global problem with `n = M.nrows()` and `nc = H.ncols() / 3`.
    ///
    /// Positive definiteness of M is checked when the solver factorizes it.
    pub fn new(
        m: CscMatrix,
        h: CscMatrix,
        f: Vec<f64>,
        w: Vec<f64>,
        mu: Vec<f64>,
    ) -> Result<Self, Error> {
        let p = Self {
            m,
            h,
            f,
            w,
            mu,
            joints: None,
        };
        p.validate()?;
        Ok(p)
    }

    /// Checks the sizes and values the constructors check. The fields are public, so a
    /// solver checks them again: a field changed after construction gets an error, not a
    /// wrong answer.
    pub fn validate(&self) -> Result<(), Error> {
        let n = self.m.nrows();
        check_shape("M", &self.m, n, n)?;
        let nc = contacts("H", &self.h, self.mu.len())?;
        check_shape("H", &self.h, n, 3 * nc)?;
        check_len("f", &self.f, n)?;
        check_len("w", &self.w, 3 * nc)?;
        check_mu(&self.mu, nc)?;
        if let Some(j) = &self.joints {
            j.validate(n)?;
        }
        Ok(())
    }

    /// Adds bilateral constraints `G^T v + b = 0` (`G` is `n x p`): joint rows without
    /// bounds or compliance ([`GlobalProblem::with_joint_bounds`] and
    /// [`GlobalProblem::with_joint_compliance`] add them).
    pub fn with_joints(mut self, g: CscMatrix, b: Vec<f64>) -> Result<Self, Error> {
        check_shape("G", &g, self.n(), g.ncols())?;
        check_len("b", &b, g.ncols())?;
        let p = g.ncols();
        self.joints = if p == 0 {
            None
        } else {
            Some(Joints {
                g,
                b,
                lo: vec![f64::NEG_INFINITY; p],
                hi: vec![f64::INFINITY; p],
                compliance: vec![0.0; p],
                friction_contact: vec![None; p],
                friction: vec![0.0; p],
            })
        };
        Ok(self)
    }

    /// Bounds `lo <= lambda <= hi` on the joint rows' multipliers (`-inf`/`+inf` for none).
    /// Without joints the bounds must be empty.
    pub fn with_joint_bounds(mut self, lo: Vec<f64>, hi: Vec<f64>) -> Result<Self, Error> {
        check_bounds(&lo, &hi, self.n_joints())?;
        if let Some(j) = &mut self.joints {
            j.lo = lo;
            j.hi = hi;
        }
        Ok(self)
    }

    /// Compliances `c >= 0` of the joint rows: row `k` reads `G_k^T v + b_k + c_k lambda_k`.
    /// Without joints the compliances must be empty.
    pub fn with_joint_compliance(mut self, c: Vec<f64>) -> Result<Self, Error> {
        check_compliance(&c, self.n_joints())?;
        if let Some(j) = &mut self.joints {
            j.compliance = c;
        }
        Ok(self)
    }

    /// Rows whose bounds follow a contact's normal impulse, `|lambda_k| <= e_k r_n(i)` with
    /// `i = contact[k]` and `e_k = coefficient[k]` (`None` and 0 for the other rows), on top
    /// of their own `lo_k <= lambda_k <= hi_k`, which must hold zero: rolling friction is
    /// such a row on a relative angular velocity about a tangent, spinning friction about
    /// the normal, with `e` in length units. Without joints both must be empty.
    pub fn with_joint_friction(
        mut self,
        contact: Vec<Option<usize>>,
        coefficient: Vec<f64>,
    ) -> Result<Self, Error> {
        let p = self.n_joints();
        if contact.len() != p {
            return Err(Error::Dimension {
                field: "friction_contact",
                expected: p,
                found: contact.len(),
            });
        }
        if let Some(index) = contact
            .iter()
            .position(|c| c.is_some_and(|i| i >= self.n_contacts()))
        {
            return Err(Error::InvalidValue {
                field: "friction_contact",
                index,
                reason: "no such contact",
            });
        }
        check_friction(&contact, &coefficient, p)?;
        if let Some(j) = &mut self.joints {
            j.friction_contact = contact;
            j.friction = coefficient;
            j.validate(self.m.nrows())?;
        }
        Ok(self)
    }

    /// Whether any joint row takes its bounds from a contact's normal impulse.
    pub fn has_contact_bounds(&self) -> bool {
        self.joints.as_ref().is_some_and(Joints::has_contact_bounds)
    }

    /// The joint rows with a finite bound (none without joints).
    pub(crate) fn bounded_rows(&self) -> Vec<usize> {
        self.joints
            .as_ref()
            .map_or_else(Vec::new, Joints::bounded_rows)
    }

    /// Number of joint multipliers (0 without joints).
    pub fn n_joints(&self) -> usize {
        self.joints.as_ref().map_or(0, |j| j.b.len())
    }

    /// Number of velocity degrees of freedom.
    pub fn n(&self) -> usize {
        self.m.nrows()
    }
    /// Number of contacts.
    pub fn n_contacts(&self) -> usize {
        self.mu.len()
    }

    /// True when a solver built for this problem can take the values of `other`
    /// ([`crate::Solver::update_values`]): same sizes and sparsity patterns of M, H and G.
    pub fn same_pattern(&self, other: &GlobalProblem) -> bool {
        self.check_successor(other).is_ok()
    }

    /// The check of an update: `next` has this problem's sizes and sparsity patterns.
    pub(crate) fn check_successor(&self, next: &GlobalProblem) -> Result<(), Error> {
        check_same_sizes([self.n(), self.n_contacts()], [next.n(), next.n_contacts()])?;
        check_pattern("M", &self.m, &next.m)?;
        check_pattern("H", &self.h, &next.h)?;
        match (&self.joints, &next.joints) {
            (None, None) => Ok(()),
            (Some(a), Some(b)) => {
                check_pattern("G", &a.g, &b.g)?;
                // A bounded row is in the ADMM splitting and an equality in the v-update
                // system: which is which is part of the system's pattern.
                match a.same_bounded_rows(b) {
                    true => Ok(()),
                    false => Err(Error::PatternChanged {
                        field: "joint bounds (which rows are bounded)",
                    }),
                }
            }
            (a, b) => Err(Error::Dimension {
                field: "G",
                expected: a.as_ref().map_or(0, |j| j.g.ncols()),
                found: b.as_ref().map_or(0, |j| j.g.ncols()),
            }),
        }
    }
}

impl GlobalProblem {
    /// Takes new values on the same sizes and patterns (`None` keeps a value). Everything
    /// is checked before anything changes; no allocation.
    pub(crate) fn set_values(&mut self, v: &NewValues) -> Result<(), Error> {
        if v.delassus.is_some() || v.q.is_some() {
            return Err(Error::Unsupported(
                "update_values: W and q belong to a local problem, the solver holds a global one"
                    .into(),
            ));
        }
        let (n, m) = (self.n(), self.w.len());
        for (field, x, len) in [("f", v.f, n), ("w", v.w, m)] {
            if let Some(x) = x {
                check_len(field, x, len)?;
            }
        }
        if let Some(x) = v.mu {
            check_mu(x, self.mu.len())?;
        }
        if let Some(x) = v.m {
            self.m.check_values("M", x)?;
        }
        if let Some(x) = v.h {
            self.h.check_values("H", x)?;
        }
        match &self.joints {
            None if [v.g, v.b, v.lo, v.hi, v.compliance, v.friction]
                .iter()
                .any(Option::is_some) =>
            {
                return Err(Error::Unsupported(
                    "update_values: G, b, bounds or compliance given, but the problem has no \
                     joints"
                        .into(),
                ))
            }
            None => {}
            Some(j) => j.check_values(v)?,
        }
        let set = |dst: &mut CscMatrix, field, src: Option<&[f64]>| match src {
            Some(src) => dst.set_values(field, src),
            None => Ok(()),
        };
        set(&mut self.m, "M", v.m)?;
        set(&mut self.h, "H", v.h)?;
        if let Some(j) = &mut self.joints {
            set(&mut j.g, "G", v.g)?;
            let rows = [
                (&mut j.b, v.b),
                (&mut j.lo, v.lo),
                (&mut j.hi, v.hi),
                (&mut j.compliance, v.compliance),
                (&mut j.friction, v.friction),
            ];
            for (dst, src) in rows {
                if let Some(src) = src {
                    dst.copy_from_slice(src);
                }
            }
        }
        for (dst, src) in [(&mut self.f, v.f), (&mut self.w, v.w), (&mut self.mu, v.mu)] {
            if let Some(src) = src {
                dst.copy_from_slice(src);
            }
        }
        Ok(())
    }
}

impl LocalProblem {
    /// Takes new values on the same sizes and pattern (`None` keeps a value). Everything
    /// is checked before anything changes; no allocation.
    pub(crate) fn set_values(&mut self, v: &NewValues) -> Result<(), Error> {
        let global = [
            v.m,
            v.h,
            v.g,
            v.f,
            v.w,
            v.b,
            v.lo,
            v.hi,
            v.compliance,
            v.friction,
        ];
        if global.iter().any(Option::is_some) {
            return Err(Error::Unsupported(
                "update_values: M, H, G, f, w, b and the joint bounds, compliance and friction belong \
                 to a global problem, the solver holds a local one"
                    .into(),
            ));
        }
        if let Some(x) = v.q {
            check_len("q", x, self.q.len())?;
        }
        if let Some(x) = v.mu {
            check_mu(x, self.mu.len())?;
        }
        if let Some(x) = v.delassus {
            self.w.set_values("W", x)?;
        }
        for (dst, src) in [(&mut self.q, v.q), (&mut self.mu, v.mu)] {
            if let Some(src) = src {
                dst.copy_from_slice(src);
            }
        }
        Ok(())
    }

    /// Validates and builds a local problem with `nc = W.ncols() / 3`.
    pub fn new(w: CscMatrix, q: Vec<f64>, mu: Vec<f64>) -> Result<Self, Error> {
        let p = Self { w, q, mu };
        p.validate()?;
        Ok(p)
    }

    /// Checks the sizes and values the constructor checks (see
    /// [`GlobalProblem::validate`]).
    pub fn validate(&self) -> Result<(), Error> {
        let nc = contacts("W", &self.w, self.mu.len())?;
        check_shape("W", &self.w, 3 * nc, 3 * nc)?;
        check_len("q", &self.q, 3 * nc)?;
        check_mu(&self.mu, nc)
    }

    /// Number of contacts.
    pub fn n_contacts(&self) -> usize {
        self.mu.len()
    }

    /// A problem of `nc` contacts on a dense pattern of W (the identity, q and mu zero),
    /// for a solver whose values are set later: any Delassus matrix of that size fits it.
    pub(crate) fn dense(nc: usize) -> Result<Self, Error> {
        let m = 3 * nc;
        let colptr = (0..=m).map(|j| j * m).collect();
        let rowind = (0..m * m).map(|k| k % m).collect();
        let mut values = vec![0.0; m * m];
        for i in 0..m {
            values[i + i * m] = 1.0;
        }
        let w = CscMatrix::new("W", m, m, colptr, rowind, values)?;
        Self::new(w, vec![0.0; m], vec![0.0; nc])
    }

    /// The check of an update: `next` has this problem's sizes and sparsity pattern.
    pub(crate) fn check_successor(&self, next: &LocalProblem) -> Result<(), Error> {
        check_same_sizes([0, self.n_contacts()], [0, next.n_contacts()])?;
        check_pattern("W", &self.w, &next.w)
    }
}

impl Problem {
    /// Checks the sizes and values of either form (see [`GlobalProblem::validate`]).
    pub fn validate(&self) -> Result<(), Error> {
        match self {
            Problem::Global(g) => g.validate(),
            Problem::Local(l) => l.validate(),
        }
    }

    /// Number of contacts.
    pub fn n_contacts(&self) -> usize {
        match self {
            Problem::Global(g) => g.n_contacts(),
            Problem::Local(l) => l.n_contacts(),
        }
    }
    /// Number of joint multipliers (0 without joints, and for a local problem).
    pub fn n_joints(&self) -> usize {
        match self {
            Problem::Global(g) => g.n_joints(),
            Problem::Local(_) => 0,
        }
    }
    /// Friction coefficients.
    pub fn mu(&self) -> &[f64] {
        match self {
            Problem::Global(g) => &g.mu,
            Problem::Local(l) => &l.mu,
        }
    }
    /// Length of the velocity vector `v` (0 for a local problem).
    pub fn n_velocities(&self) -> usize {
        match self {
            Problem::Global(g) => g.n(),
            Problem::Local(_) => 0,
        }
    }
    /// The uncoupled union of problems of one form: block-diagonal M, H, G (global) or W
    /// (local), the vectors one after the other. A scene of separate piles is such a
    /// problem; a solver finds the blocks again as islands.
    pub fn block_diagonal(parts: &[Problem]) -> Result<Problem, Error> {
        fn stack<'a>(
            field: &'static str,
            blocks: impl Iterator<Item = &'a CscMatrix>,
        ) -> Result<CscMatrix, Error> {
            let (mut nrows, mut colptr, mut rowind, mut values) = (0, vec![0], vec![], vec![]);
            for b in blocks {
                for j in 0..b.ncols() {
                    for (i, x) in b.col(j) {
                        rowind.push(nrows + i);
                        values.push(x);
                    }
                    colptr.push(rowind.len());
                }
                nrows += b.nrows();
            }
            let ncols = colptr.len() - 1;
            CscMatrix::new(field, nrows, ncols, colptr, rowind, values)
        }
        let concat = |x: &mut dyn Iterator<Item = &Vec<f64>>| x.flatten().copied().collect();
        let globals: Vec<&GlobalProblem> = parts
            .iter()
            .filter_map(|p| match p {
                Problem::Global(g) => Some(g),
                Problem::Local(_) => None,
            })
            .collect();
        if globals.len() == parts.len() && !parts.is_empty() {
            let p = GlobalProblem::new(
                stack("M", globals.iter().map(|g| &g.m))?,
                stack("H", globals.iter().map(|g| &g.h))?,
                concat(&mut globals.iter().map(|g| &g.f)),
                concat(&mut globals.iter().map(|g| &g.w)),
                concat(&mut globals.iter().map(|g| &g.mu)),
            )?;
            if !globals.iter().any(|g| g.joints.is_some()) {
                return Ok(Problem::Global(p));
            }
            let empty = |n: usize| CscMatrix::new("G", n, 0, vec![0], vec![], vec![]);
            let joints = globals
                .iter()
                .map(|g| match &g.joints {
                    Some(j) => Ok(j.clone()),
                    None => empty(g.n()).map(Joints::none),
                })
                .collect::<Result<Vec<_>, Error>>()?;
            let g = stack("G", joints.iter().map(|j| &j.g))?;
            let p = p
                .with_joints(g, concat(&mut joints.iter().map(|j| &j.b)))?
                .with_joint_bounds(
                    concat(&mut joints.iter().map(|j| &j.lo)),
                    concat(&mut joints.iter().map(|j| &j.hi)),
                )?
                .with_joint_compliance(concat(&mut joints.iter().map(|j| &j.compliance)))?;
            let contact = stacked_contacts(&globals, &joints);
            let p =
                p.with_joint_friction(contact, concat(&mut joints.iter().map(|j| &j.friction)))?;
            return Ok(Problem::Global(p));
        }
        let locals: Vec<&LocalProblem> = parts
            .iter()
            .filter_map(|p| match p {
                Problem::Local(l) => Some(l),
                Problem::Global(_) => None,
            })
            .collect();
        if locals.len() != parts.len() || parts.is_empty() {
            return Err(Error::Unsupported(
                "block_diagonal: the problems must be one or more of the same form".into(),
            ));
        }
        Ok(Problem::Local(LocalProblem::new(
            stack("W", locals.iter().map(|l| &l.w))?,
            concat(&mut locals.iter().map(|l| &l.q)),
            concat(&mut locals.iter().map(|l| &l.mu)),
        )?))
    }

    /// Takes new values on the same sizes and patterns (see [`NewValues`]).
    pub(crate) fn set_values(&mut self, v: &NewValues) -> Result<(), Error> {
        match self {
            Problem::Global(g) => g.set_values(v),
            Problem::Local(l) => l.set_values(v),
        }
    }
    /// True when the two problems have the same sizes and sparsity patterns, so a solver
    /// built for one can be updated to the other with a numeric refactorization only.
    pub fn same_pattern(&self, other: &Problem) -> bool {
        self.check_successor(other).is_ok()
    }

    /// The one check of an update ([`crate::Solver::update`]): same form
    /// (`Error::Unsupported`), sizes (`Error::Dimension`) and sparsity patterns
    /// (`Error::PatternChanged`).
    pub(crate) fn check_successor(&self, next: &Problem) -> Result<(), Error> {
        match (self, next) {
            (Problem::Global(a), Problem::Global(b)) => a.check_successor(b),
            (Problem::Local(a), Problem::Local(b)) => a.check_successor(b),
            (Problem::Global(_), Problem::Local(_)) => Err(Error::Unsupported(
                "update: the new problem is local, the solver was built for a global one".into(),
            )),
            (Problem::Local(_), Problem::Global(_)) => Err(Error::Unsupported(
                "update: the new problem is global, the solver was built for a local one".into(),
            )),
        }
    }
}

/// Same shape and non-zero positions, as a [`Error::PatternChanged`] naming `field`.
fn check_pattern(field: &'static str, a: &CscMatrix, b: &CscMatrix) -> Result<(), Error> {
    check_shape(field, b, a.nrows(), a.ncols())?;
    match a.colptr() == b.colptr() && a.rowind() == b.rowind() {
        true => Ok(()),
        false => Err(Error::PatternChanged { field }),
    }
}

/// New values for the problem a solver holds: the next time step of a scene whose sizes
/// and sparsity patterns did not change ([`crate::Solver::update_values`]). `None` keeps
/// the current values. Matrix values come in the order of the arrays the matrix was built
/// from. Fields of the other form must be `None`.
#[derive(Debug, Clone, Copy, Default)]
pub struct NewValues<'a> {
    /// Global form: values of `M`.
    pub m: Option<&'a [f64]>,
    /// Global form: values of `H`.
    pub h: Option<&'a [f64]>,
    /// Global form with joints: values of `G`.
    pub g: Option<&'a [f64]>,
    /// Global form: `f`.
    pub f: Option<&'a [f64]>,
    /// Global form: `w`.
    pub w: Option<&'a [f64]>,
    /// Global form with joints: `b`.
    pub b: Option<&'a [f64]>,
    /// Global form with joints: lower bounds of the multipliers. Which rows are bounded
    /// (a finite bound on either side) cannot change.
    pub lo: Option<&'a [f64]>,
    /// Global form with joints: upper bounds of the multipliers (same rule as `lo`).
    pub hi: Option<&'a [f64]>,
    /// Global form with joints: compliances.
    pub compliance: Option<&'a [f64]>,
    /// Global form with joints: coefficients of the rows bounded by contacts (which rows
    /// and which contacts cannot change).
    pub friction: Option<&'a [f64]>,
    /// Both forms: friction coefficients.
    pub mu: Option<&'a [f64]>,
    /// Local form: values of the Delassus matrix `W`.
    pub delassus: Option<&'a [f64]>,
    /// Local form: `q`.
    pub q: Option<&'a [f64]>,
}

impl NewValues<'static> {
    /// Every field named: what an update that replaces the whole problem hands each part
    /// of a scene, or keeps for undoing (only which fields are `Some` matters).
    pub(crate) const EVERY_FIELD: Self = NewValues {
        m: Some(&[]),
        h: Some(&[]),
        g: Some(&[]),
        f: Some(&[]),
        w: Some(&[]),
        b: Some(&[]),
        lo: Some(&[]),
        hi: Some(&[]),
        compliance: Some(&[]),
        friction: Some(&[]),
        mu: Some(&[]),
        delassus: Some(&[]),
        q: Some(&[]),
    };
}

/// The contact bounding each joint row of stacked problems, in the stacked numbering (each
/// part's contacts follow the previous parts').
fn stacked_contacts(parts: &[&GlobalProblem], joints: &[Joints]) -> Vec<Option<usize>> {
    let mut first = 0;
    let mut out = Vec::new();
    for (g, j) in parts.iter().zip(joints) {
        out.extend(j.friction_contact.iter().map(|c| c.map(|i| first + i)));
        first += g.n_contacts();
    }
    out
}

/// Copies of a problem's current values for the fields an update names, taken before the
/// update so that one refused after its values were taken (a matrix that does not
/// factorize) can be undone: a refused update changes nothing. The buffers are reused
/// from one update to the next.
#[derive(Debug, Clone, Default)]
pub(crate) struct KeptValues {
    /// `m, h, g, f, w, b, mu, delassus, q, lo, hi, compliance, friction`, each with
    /// whether it was kept.
    fields: [(bool, Vec<f64>); 13],
}

impl KeptValues {
    /// Keeps `p`'s values of the fields `given` names (fields `p` lacks are not kept).
    /// Matrix values are kept in the caller's order, as an update takes them.
    pub(crate) fn keep(&mut self, p: ProblemRef<'_>, given: &NewValues) {
        let fields = &mut self.fields;
        for (kept, _) in fields.iter_mut() {
            *kept = false;
        }
        // Field `k` (in `NewValues` order) from a vector or a matrix, when the update names it.
        let mut vector = |k: usize, named: Option<&[f64]>, x: &[f64]| {
            if named.is_some() {
                fields[k].1.clear();
                fields[k].1.extend_from_slice(x);
                fields[k].0 = true;
            }
        };
        match p {
            ProblemRef::Global(p) => {
                vector(3, given.f, &p.f);
                vector(4, given.w, &p.w);
                vector(6, given.mu, &p.mu);
                if let Some(j) = &p.joints {
                    vector(5, given.b, &j.b);
                    vector(9, given.lo, &j.lo);
                    vector(10, given.hi, &j.hi);
                    vector(11, given.compliance, &j.compliance);
                    vector(12, given.friction, &j.friction);
                }
            }
            ProblemRef::Local(p) => {
                vector(6, given.mu, &p.mu);
                vector(8, given.q, &p.q);
            }
        }
        let mut matrix = |k: usize, named: Option<&[f64]>, a: &CscMatrix| {
            if named.is_some() {
                a.values_in_input_order(&mut fields[k].1);
                fields[k].0 = true;
            }
        };
        match p {
            ProblemRef::Global(p) => {
                matrix(0, given.m, &p.m);
                matrix(1, given.h, &p.h);
                if let Some(j) = &p.joints {
                    matrix(2, given.g, &j.g);
                }
            }
            ProblemRef::Local(p) => matrix(7, given.delassus, &p.w),
        }
    }

    /// The kept values, as an update that puts them back.
    pub(crate) fn values(&self) -> NewValues<'_> {
        let [m, h, g, f, w, b, mu, delassus, q, lo, hi, compliance, friction] =
            std::array::from_fn(|k| self.fields[k].0.then_some(&self.fields[k].1[..]));
        NewValues {
            m,
            h,
            g,
            f,
            w,
            b,
            lo,
            hi,
            compliance,
            friction,
            mu,
            delassus,
            q,
        }
    }
}

/// A borrowed problem of either form.
#[derive(Debug, Clone, Copy)]
pub(crate) enum ProblemRef<'a> {
    /// Global form.
    Global(&'a GlobalProblem),
    /// Local form.
    Local(&'a LocalProblem),
}

impl<'a> From<&'a Problem> for ProblemRef<'a> {
    fn from(p: &'a Problem) -> Self {
        match p {
            Problem::Global(g) => Self::Global(g),
            Problem::Local(l) => Self::Local(l),
        }
    }
}
