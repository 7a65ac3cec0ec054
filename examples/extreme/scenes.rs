//! Extreme contact scenes built in code, shared by `examples/extreme.rs` and
//! `tests/extreme.rs`: stiff mass ratios, extreme and mixed friction, unit scalings,
//! redundant contacts, near-singular inertia, many contacts, an impact, separating and empty
//! contact sets, and a granular pile.
//!
//! Every body is rigid with 6 velocity degrees of freedom `(v, omega)` in the world frame,
//! its centre of mass as reference point, axes aligned with the world so that `M` is
//! diagonal. One time step `h` of Moreau-Jean: `M v = H r + f` with `f = M v_prev + h F`.
//! A contact between body `a` and body `b` (or the ground) has frame `(n, t1, t2)`, `n`
//! pointing from `b` to `a`; the impulse `r` acts on `a` (and `-r` on `b`), and
//! `u = H^T v + w` is the velocity of `a` relative to `b` at the contact point.

// Dense reference code indexes rows and columns by number on purpose.
#![allow(clippy::needless_range_loop)]
#![allow(dead_code)]

use cadmm::{
    CscMatrix, GlobalProblem, LocalProblem, Problem, Settings, Solution, Solver, VariantChoice,
};
use std::time::Instant;

pub type V3 = [f64; 3];

/// Gravity (m/s^2) and time step (s) of every scene.
pub const GRAVITY: f64 = 9.81;
pub const STEP: f64 = 0.01;

/// A rigid body: mass, principal inertia, position of its centre of mass, velocity before
/// the step, applied force and torque over the step (gravity included by [`Scene::body`]).
#[derive(Clone)]
pub struct Body {
    pub mass: f64,
    pub inertia: V3,
    pub x: V3,
    pub v: V3,
    pub omega: V3,
    pub force: V3,
    pub torque: V3,
}

/// A contact point of body `a` on body `b` (`None`: the fixed ground).
#[derive(Clone)]
pub struct Contact {
    pub a: usize,
    pub b: Option<usize>,
    pub point: V3,
    pub normal: V3,
    pub mu: f64,
    /// Free relative velocity added to `H^T v` (a gap or restitution term).
    pub w: V3,
}

/// Bodies and contacts, assembled into a global problem.
#[derive(Clone, Default)]
pub struct Scene {
    pub bodies: Vec<Body>,
    pub contacts: Vec<Contact>,
}

fn cross(p: V3, d: V3) -> V3 {
    [
        p[1] * d[2] - p[2] * d[1],
        p[2] * d[0] - p[0] * d[2],
        p[0] * d[1] - p[1] * d[0],
    ]
}

fn sub(p: V3, q: V3) -> V3 {
    [p[0] - q[0], p[1] - q[1], p[2] - q[2]]
}

fn unit(p: V3) -> V3 {
    let n = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    [p[0] / n, p[1] / n, p[2] / n]
}

/// Orthonormal contact frame `(n, t1, t2)` with `t2 = n x t1`.
fn frame(n: V3) -> [V3; 3] {
    let n = unit(n);
    let helper = if n[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let t1 = unit(cross(helper, n));
    [n, t1, cross(n, t1)]
}

/// Principal inertia of a box of mass `m` and full side lengths `s`.
pub fn box_inertia(m: f64, s: V3) -> V3 {
    [
        m * (s[1] * s[1] + s[2] * s[2]) / 12.0,
        m * (s[0] * s[0] + s[2] * s[2]) / 12.0,
        m * (s[0] * s[0] + s[1] * s[1]) / 12.0,
    ]
}

impl Scene {
    /// Adds a body at rest at `x` under gravity; returns its index.
    pub fn body(&mut self, mass: f64, inertia: V3, x: V3) -> usize {
        self.bodies.push(Body {
            mass,
            inertia,
            x,
            v: [0.0; 3],
            omega: [0.0; 3],
            force: [0.0, 0.0, -mass * GRAVITY],
            torque: [0.0; 3],
        });
        self.bodies.len() - 1
    }

    pub fn contact(&mut self, a: usize, b: Option<usize>, point: V3, normal: V3, mu: f64) {
        self.contacts.push(Contact {
            a,
            b,
            point,
            normal,
            mu,
            w: [0.0; 3],
        });
    }

    /// The four bottom corners of box `a` (side lengths `s`) resting on `b` (or the ground).
    pub fn corners(&mut self, a: usize, b: Option<usize>, s: V3, mu: [f64; 4]) {
        let x = self.bodies[a].x;
        let (hx, hy, hz) = (s[0] / 2.0, s[1] / 2.0, s[2] / 2.0);
        for (k, (sx, sy)) in [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)]
            .into_iter()
            .enumerate()
        {
            let p = [x[0] + sx * hx, x[1] + sy * hy, x[2] - hz];
            self.contact(a, b, p, [0.0, 0.0, 1.0], mu[k]);
        }
    }

    /// `M`, `H`, `f = M v_prev + h F`, `w`, `mu`.
    pub fn global(&self) -> GlobalProblem {
        let n = 6 * self.bodies.len();
        let mut m = Vec::with_capacity(n);
        let mut f = Vec::with_capacity(n);
        for b in &self.bodies {
            let diag = [
                b.mass,
                b.mass,
                b.mass,
                b.inertia[0],
                b.inertia[1],
                b.inertia[2],
            ];
            let vel = [b.v[0], b.v[1], b.v[2], b.omega[0], b.omega[1], b.omega[2]];
            let load = [
                b.force[0],
                b.force[1],
                b.force[2],
                b.torque[0],
                b.torque[1],
                b.torque[2],
            ];
            for k in 0..6 {
                let i = m.len();
                m.push((i, i, diag[k]));
                f.push(diag[k] * vel[k] + STEP * load[k]);
            }
        }
        let mut t = Vec::with_capacity(self.contacts.len() * 24);
        let mut w = Vec::with_capacity(3 * self.contacts.len());
        let mut mu = Vec::with_capacity(self.contacts.len());
        for (k, c) in self.contacts.iter().enumerate() {
            for (j, d) in frame(c.normal).into_iter().enumerate() {
                let col = 3 * k + j;
                let mut add = |body: usize, sign: f64| {
                    let arm = cross(sub(c.point, self.bodies[body].x), d);
                    for i in 0..3 {
                        if d[i] != 0.0 {
                            t.push((6 * body + i, col, sign * d[i]));
                        }
                        if arm[i] != 0.0 {
                            t.push((6 * body + 3 + i, col, sign * arm[i]));
                        }
                    }
                };
                add(c.a, 1.0);
                if let Some(b) = c.b {
                    add(b, -1.0);
                }
            }
            w.extend_from_slice(&c.w);
            mu.push(c.mu);
        }
        let m = CscMatrix::from_triplets("M", n, n, &m).expect("M");
        let h = CscMatrix::from_triplets("H", n, 3 * self.contacts.len(), &t).expect("H");
        GlobalProblem::new(m, h, f, w, mu).expect("scene problem")
    }
}

/// The Delassus form `W = H^T M^-1 H`, `q = w + H^T M^-1 f` of a problem with diagonal `M`,
/// computed here without the library (dense `W`, exact zeros dropped).
pub fn local_form(p: &GlobalProblem) -> LocalProblem {
    let n = p.n();
    let l = p.w.len();
    let mut minv = vec![0.0; n];
    for j in 0..n {
        for (i, v) in p.m.col(j) {
            assert_eq!(i, j, "local_form needs a diagonal M");
            minv[j] = 1.0 / v;
        }
    }
    // Columns of H as sparse lists; W_ij = sum_k H_ki H_kj / M_kk.
    let cols: Vec<Vec<(usize, f64)>> = (0..l).map(|j| p.h.col(j).collect()).collect();
    let mut dense_col = vec![0.0; n];
    let mut t = Vec::new();
    for j in 0..l {
        for &(k, v) in &cols[j] {
            dense_col[k] = v * minv[k];
        }
        for i in 0..l {
            let s: f64 = cols[i].iter().map(|&(k, v)| v * dense_col[k]).sum();
            if s != 0.0 {
                t.push((i, j, s));
            }
        }
        for &(k, _) in &cols[j] {
            dense_col[k] = 0.0;
        }
    }
    let w = CscMatrix::from_triplets("W", l, l, &t).expect("W");
    let mf: Vec<f64> = (0..n).map(|k| minv[k] * p.f[k]).collect();
    let q: Vec<f64> = (0..l)
        .map(|j| p.w[j] + cols[j].iter().map(|&(k, v)| v * mf[k]).sum::<f64>())
        .collect();
    LocalProblem::new(w, q, p.mu.clone()).expect("local form")
}

/// The same problem in other units: lengths multiplied by `a`, masses by `b`, times by `c`
/// (a value `x` in the old units is `a x` in the new ones when `x` is a length...). With
/// `T = diag(1, 1, 1, a, a, a)` per body (angular rows carry a lever arm):
///
/// - velocities `v = (v_lin, omega)`: `v_lin` is length/time, `omega` 1/time, so
///   `v' = (a / c) T^-1 v`;
/// - impulses `r` (mass length / time): `r' = (a b / c) r`;
/// - `M = diag(m, I)`: `m` scales by `b`, `I` (mass length^2) by `a^2 b`: `M' = b T M T`;
/// - `H` maps `r` to (force, torque) impulses; its angular rows are lever arms: `H' = T H`;
/// - `f = M v_prev + h F` is an impulse per row: `f' = (a b / c) T f`;
/// - `w` is a velocity: `w' = (a / c) w`; `mu` is a ratio and does not change.
///
/// Then `M' v' = (a b / c) T M v`, `H' r' = (a b / c) T H r`, so `M' v' = H' r' + f'` holds
/// exactly when `M v = H r + f` does, and `u' = H'^T v' + w' = (a / c) u`.
pub fn scale_units(p: &GlobalProblem, a: f64, b: f64, c: f64) -> GlobalProblem {
    let t = |i: usize| if i % 6 >= 3 { a } else { 1.0 };
    let scale_rows = |x: &CscMatrix, both: bool, k: f64| {
        let mut tr = Vec::with_capacity(x.nnz());
        for j in 0..x.ncols() {
            for (i, v) in x.col(j) {
                let s = if both { t(i) * t(j) } else { t(i) };
                tr.push((i, j, k * s * v));
            }
        }
        tr
    };
    let n = p.n();
    let m = CscMatrix::from_triplets("M", n, n, &scale_rows(&p.m, true, b)).expect("M");
    let h =
        CscMatrix::from_triplets("H", n, p.h.ncols(), &scale_rows(&p.h, false, 1.0)).expect("H");
    let f = (0..n).map(|i| a * b / c * t(i) * p.f[i]).collect();
    let w = p.w.iter().map(|x| a / c * x).collect();
    GlobalProblem::new(m, h, f, w, p.mu.clone()).expect("scaled problem")
}

/// One case: its name, the family it belongs to, the global problem and, where it is
/// meaningful and small enough, its local form.
pub struct Case {
    pub name: String,
    pub family: &'static str,
    pub global: GlobalProblem,
    pub local: Option<LocalProblem>,
}

/// Largest `3 nc` for which a case also gets a (dense) local form.
const LOCAL_MAX: usize = 1500;

fn case(name: impl Into<String>, family: &'static str, scene: &Scene) -> Case {
    let global = scene.global();
    let local =
        (global.w.len() <= LOCAL_MAX && global.n_contacts() > 0).then(|| local_form(&global));
    Case {
        name: name.into(),
        family,
        global,
        local,
    }
}

const UNIT: V3 = [1.0, 1.0, 1.0];

/// A box of mass `top` on a box of mass `bottom` on the ground, four corners each.
fn two_boxes(bottom: f64, top: f64, mu: [f64; 8], push: f64) -> Scene {
    let mut s = Scene::default();
    let lower = s.body(bottom, box_inertia(bottom, UNIT), [0.0, 0.0, 0.5]);
    let upper = s.body(top, box_inertia(top, UNIT), [0.0, 0.0, 1.5]);
    s.bodies[upper].force[0] = push * top * GRAVITY;
    s.corners(lower, None, UNIT, [mu[0], mu[1], mu[2], mu[3]]);
    s.corners(upper, Some(lower), UNIT, [mu[4], mu[5], mu[6], mu[7]]);
    s
}

/// A vertical chain of `count` boxes, masses alternating 1 and `ratio`.
fn chain(count: usize, ratio: f64) -> Scene {
    let mut s = Scene::default();
    for k in 0..count {
        let m = if k % 2 == 0 { 1.0 } else { ratio };
        let i = s.body(m, box_inertia(m, UNIT), [0.0, 0.0, 0.5 + k as f64]);
        let below = k.checked_sub(1);
        s.corners(i, below, UNIT, [0.3; 4]);
    }
    // A sideways push on the top box.
    let top = count - 1;
    s.bodies[top].force[0] = 0.1 * s.bodies[top].mass * GRAVITY;
    s
}

/// A unit box on the ground by its four corners, pushed sideways by `push` times its weight.
fn box_pushed(mu: f64, push: f64) -> Scene {
    let mut s = Scene::default();
    let b = s.body(1.0, box_inertia(1.0, UNIT), [0.0, 0.0, 0.5]);
    s.bodies[b].force[0] = push * GRAVITY;
    s.corners(b, None, UNIT, [mu; 4]);
    s
}

/// The base scene of the unit-scaling family: a box on three points (no redundancy),
/// pushed sideways off its centre, so it both slides and turns.
fn tripod() -> Scene {
    let mut s = Scene::default();
    let b = s.body(2.0, box_inertia(2.0, [1.0, 0.8, 0.4]), [0.0, 0.0, 0.2]);
    s.bodies[b].force[0] = 0.5 * 2.0 * GRAVITY;
    s.bodies[b].torque[2] = 0.3;
    for p in [[0.5, 0.0, 0.0], [-0.5, 0.4, 0.0], [-0.5, -0.4, 0.0]] {
        s.contact(b, None, p, [0.0, 0.0, 1.0], 0.3);
    }
    s
}

/// A deterministic uniform generator on [0, 1) (xorshift64 from `seed`).
fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A sphere lattice `nx x ny x nz` (radius 0.5, masses between 0.5 and 1.5, small random
/// velocities) in contact with its vertical and horizontal neighbours and the ground.
pub fn pile(nx: usize, ny: usize, nz: usize) -> Scene {
    let mut s = Scene::default();
    let mut rand = uniform(0x2545_F491_4F6C_DD1D);
    let id = |i: usize, j: usize, k: usize| (k * ny + j) * nx + i;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let m = 0.5 + rand();
                let b = s.body(m, [0.1 * m; 3], [i as f64, j as f64, 0.5 + k as f64]);
                s.bodies[b].v = [0.1 * (rand() - 0.5), 0.1 * (rand() - 0.5), -0.1 * rand()];
            }
        }
    }
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let b = id(i, j, k);
                let x = s.bodies[b].x;
                let below = k.checked_sub(1).map(|k| id(i, j, k));
                s.contact(b, below, [x[0], x[1], x[2] - 0.5], [0.0, 0.0, 1.0], 0.5);
                if i > 0 {
                    s.contact(
                        b,
                        Some(id(i - 1, j, k)),
                        [x[0] - 0.5, x[1], x[2]],
                        [1.0, 0.0, 0.0],
                        0.5,
                    );
                }
                if j > 0 {
                    s.contact(
                        b,
                        Some(id(i, j - 1, k)),
                        [x[0], x[1] - 0.5, x[2]],
                        [0.0, 1.0, 0.0],
                        0.5,
                    );
                }
            }
        }
    }
    s
}

/// How [`irregular_pile_shaped`] draws its spheres and contacts: the scale benchmark varies
/// these so that no figure holds on one generator's piles alone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PileShape {
    /// Radii are uniform in `[r_min, r_max]`, `r_max <= 0.5` (the lattice's spacing is 1).
    pub r_min: f64,
    /// See `r_min`.
    pub r_max: f64,
    /// A drop site moves at most this fraction of `0.5 - r` from its lattice site.
    pub jitter: f64,
    /// Two spheres (or a sphere and the ground) are in contact when their gap is below this
    /// fraction of the smaller radius.
    pub gap_fraction: f64,
    /// Every contact's friction coefficient.
    pub mu: f64,
    /// Seed of the radii, sites and velocities.
    pub seed: u64,
}

/// The shape of [`irregular_pile`], the scale benchmark's first pile.
pub const PILE_SHAPE: PileShape = PileShape {
    r_min: 0.35,
    r_max: 0.5,
    jitter: 1.0,
    gap_fraction: 0.1,
    mu: 0.5,
    seed: 0x9E37_79B9_7F4A_7C15,
};

/// The upper of the two points at distances `d` from the centres `c` (a sphere resting on
/// three), if they exist.
fn touching(c: [V3; 3], d: [f64; 3]) -> Option<V3> {
    let dot = |p: V3, q: V3| p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
    let (a, b) = (sub(c[1], c[0]), sub(c[2], c[0]));
    let e = dot(a, a).sqrt();
    let ex = [a[0] / e, a[1] / e, a[2] / e];
    let i = dot(ex, b);
    let rest = [b[0] - i * ex[0], b[1] - i * ex[1], b[2] - i * ex[2]];
    let j = dot(rest, rest).sqrt();
    if e < 1e-9 || j < 1e-9 {
        return None;
    }
    let ey = [rest[0] / j, rest[1] / j, rest[2] / j];
    let mut ez = cross(ex, ey);
    if ez[2] < 0.0 {
        ez = [-ez[0], -ez[1], -ez[2]];
    }
    let x = (d[0] * d[0] - d[1] * d[1] + e * e) / (2.0 * e);
    let y = (d[0] * d[0] - d[2] * d[2] + i * i + j * j) / (2.0 * j) - i / j * x;
    let z2 = d[0] * d[0] - x * x - y * y;
    if z2 < 0.0 {
        return None;
    }
    let z = z2.sqrt();
    Some([0, 1, 2].map(|k| c[0][k] + x * ex[k] + y * ey[k] + z * ez[k]))
}

/// [`irregular_pile_shaped`] with [`PILE_SHAPE`].
pub fn irregular_pile(nx: usize, ny: usize, nz: usize) -> Scene {
    irregular_pile_shaped(nx, ny, nz, &PILE_SHAPE)
}

/// An irregular pile of about `nx x ny x nz` polydisperse spheres (radii uniform in
/// `[r_min, r_max]`, density such that a sphere of radius 0.5 weighs 1, small random
/// velocities), dropped one by one over the sites of a jittered lattice whose odd layers sit
/// over the hollows of the even ones: each settles in the lowest hollow of three spheres
/// below within 0.5 of its site, or straight down where there is none, so spheres rest on
/// spheres of other columns. Contacts join the pairs, and the spheres and the ground, whose
/// gap is below `gap_fraction` times the smaller radius: the normal joins the centres, the
/// point is midway across the gap, and `w_N = gap / STEP`, so the gap may close within the
/// step but not be crossed. No two spheres overlap. Bottom spheres that end up in no
/// contact but the ground's are left out, so the pile is one island. Deterministic.
pub fn irregular_pile_shaped(nx: usize, ny: usize, nz: usize, shape: &PileShape) -> Scene {
    let PileShape {
        r_min,
        r_max,
        jitter,
        gap_fraction,
        mu,
        seed,
    } = *shape;
    let mut s = Scene::default();
    let mut rand = uniform(seed);
    let mut radius: Vec<f64> = Vec::with_capacity(nx * ny * nz);
    // Spheres placed so far by unit column cell of the horizontal plane (cells 0..=nx, 0..=ny
    // hold every centre): a drop only looks at the 3 x 3 cells around it.
    let (cx, cy) = (nx + 2, ny + 2);
    let mut columns: Vec<Vec<usize>> = vec![Vec::new(); cx * cy];
    let cell = |x: f64| (x + 0.5).floor().max(0.0) as usize;
    for k in 0..nz {
        let shift = 0.5 * (k % 2) as f64;
        for j in 0..ny {
            for i in 0..nx {
                let r = r_min + (r_max - r_min) * rand();
                // Within the disc of radius 0.5 - r around the lattice site, so that spheres
                // of one layer never overlap.
                let (rho, phi) = (
                    jitter * (0.5 - r) * rand().sqrt(),
                    std::f64::consts::TAU * rand(),
                );
                let (x0, y0) = (
                    i as f64 + shift + rho * phi.cos(),
                    j as f64 + shift + rho * phi.sin(),
                );
                // Spheres placed near the site (two cells around: the sphere may roll up to
                // 0.5 away from it).
                let (gi, gj) = (cell(x0), cell(y0));
                let mut near = Vec::new();
                for a in gi.saturating_sub(2)..=(gi + 2).min(cx - 1) {
                    for b in gj.saturating_sub(2)..=(gj + 2).min(cy - 1) {
                        near.extend_from_slice(&columns[b * cx + a]);
                    }
                }
                // Lowest height at (x, y) clear of the ground and of every sphere near.
                let clear = |x: f64, y: f64| {
                    let mut z = r;
                    for &o in &near {
                        let p = s.bodies[o].x;
                        let reach = r + radius[o];
                        let dh2 = (x - p[0]).powi(2) + (y - p[1]).powi(2);
                        if dh2 < reach * reach {
                            z = z.max(p[2] + (reach * reach - dh2).sqrt());
                        }
                    }
                    z
                };
                // Where it settles: the lowest rest on three of the five highest spheres
                // under the site that is clear of all others and within 0.5 of the site
                // (a sphere dropped there rolls into such a hollow); else straight down.
                let mut under: Vec<(f64, usize)> = near
                    .iter()
                    .filter_map(|&o| {
                        let p = s.bodies[o].x;
                        let reach = r + radius[o];
                        let dh2 = (x0 - p[0]).powi(2) + (y0 - p[1]).powi(2);
                        (dh2 < (reach + 0.5).powi(2))
                            .then(|| (p[2] + (reach * reach - dh2).max(0.0).sqrt(), o))
                    })
                    .collect();
                under.sort_by(|a, b| b.0.total_cmp(&a.0));
                under.truncate(5);
                let mut rest: Option<V3> = None;
                for a in 0..under.len() {
                    for b in a + 1..under.len() {
                        for c in b + 1..under.len() {
                            let o = [under[a].1, under[b].1, under[c].1];
                            let Some(p) =
                                touching(o.map(|o| s.bodies[o].x), o.map(|o| r + radius[o]))
                            else {
                                continue;
                            };
                            let moved2 = (p[0] - x0).powi(2) + (p[1] - y0).powi(2);
                            if moved2 < 0.25
                                && p[2] >= clear(p[0], p[1]) - 1e-9
                                && rest.is_none_or(|q| p[2] < q[2])
                            {
                                rest = Some(p);
                            }
                        }
                    }
                }
                let [x, y, z] = rest.unwrap_or_else(|| [x0, y0, clear(x0, y0)]);
                let m = 8.0 * r * r * r;
                let body = s.body(m, [0.4 * m * r * r; 3], [x, y, z]);
                s.bodies[body].v = [0.1 * (rand() - 0.5), 0.1 * (rand() - 0.5), -0.1 * rand()];
                radius.push(r);
                columns[cell(y) * cx + cell(x)].push(body);
            }
        }
    }
    // Pairs within reach, by cells of the largest contact distance (27 cells per sphere).
    let size = 2.0 * r_max * (1.0 + gap_fraction);
    let key = |p: V3| {
        (
            (p[0] / size).floor() as i64,
            (p[1] / size).floor() as i64,
            (p[2] / size).floor() as i64,
        )
    };
    let mut grid: std::collections::HashMap<(i64, i64, i64), Vec<usize>> =
        std::collections::HashMap::new();
    for (b, body) in s.bodies.iter().enumerate() {
        grid.entry(key(body.x)).or_default().push(b);
    }
    for a in 0..s.bodies.len() {
        let (xa, ra) = (s.bodies[a].x, radius[a]);
        if xa[2] - ra < gap_fraction * ra {
            let gap = xa[2] - ra;
            s.contacts.push(Contact {
                a,
                b: None,
                point: [xa[0], xa[1], 0.5 * gap],
                normal: [0.0, 0.0, 1.0],
                mu,
                w: [gap / STEP, 0.0, 0.0],
            });
        }
        let (ka, kb, kc) = key(xa);
        for dk in -1..=1 {
            for dj in -1..=1 {
                for di in -1..=1 {
                    let Some(cell) = grid.get(&(ka + di, kb + dj, kc + dk)) else {
                        continue;
                    };
                    for &b in cell {
                        if b <= a {
                            continue;
                        }
                        let (xb, rb) = (s.bodies[b].x, radius[b]);
                        let d = sub(xa, xb);
                        let dist = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                        let gap = dist - ra - rb;
                        if gap < gap_fraction * ra.min(rb) {
                            // n from b to a; the point midway between the two surfaces.
                            let n = [d[0] / dist, d[1] / dist, d[2] / dist];
                            let t = rb + 0.5 * gap;
                            s.contacts.push(Contact {
                                a,
                                b: Some(b),
                                point: [xb[0] + t * n[0], xb[1] + t * n[1], xb[2] + t * n[2]],
                                normal: n,
                                mu,
                                w: [gap / STEP, 0.0, 0.0],
                            });
                        }
                    }
                }
            }
        }
    }
    // A few spheres of the bottom layer that nothing came to rest on touch only the
    // ground: islands of their own, left out so that the pile is one island.
    keep_largest_island(&mut s);
    s
}

/// The island of each body: its index among the groups of bodies joined by contacts between
/// bodies (a body on the ground alone is a group of its own), and the number of groups.
pub fn islands(s: &Scene) -> (Vec<usize>, usize) {
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut parent: Vec<usize> = (0..s.bodies.len()).collect();
    for c in &s.contacts {
        if let Some(b) = c.b {
            let (ra, rb) = (root(&mut parent, c.a), root(&mut parent, b));
            parent[ra] = rb;
        }
    }
    let mut index = vec![usize::MAX; s.bodies.len()];
    let mut count = 0;
    let island = (0..s.bodies.len())
        .map(|i| {
            let r = root(&mut parent, i);
            if index[r] == usize::MAX {
                index[r] = count;
                count += 1;
            }
            index[r]
        })
        .collect();
    (island, count)
}

/// Keeps the largest island of `s` (bodies renumbered in order, their contacts with it).
fn keep_largest_island(s: &mut Scene) {
    let (island, count) = islands(s);
    let mut size = vec![0usize; count];
    for &i in &island {
        size[i] += 1;
    }
    let Some(keep) = (0..count).max_by_key(|&i| size[i]) else {
        return;
    };
    let mut new_index = vec![usize::MAX; s.bodies.len()];
    let mut bodies = Vec::with_capacity(size[keep]);
    for (b, body) in s.bodies.iter().enumerate() {
        if island[b] == keep {
            new_index[b] = bodies.len();
            bodies.push(body.clone());
        }
    }
    s.contacts.retain(|c| island[c.a] == keep);
    for c in &mut s.contacts {
        c.a = new_index[c.a];
        c.b = c.b.map(|b| new_index[b]);
    }
    s.bodies = bodies;
}

/// Mass ratios of the stiff family.
pub const RATIOS: [f64; 5] = [1.0, 1e2, 1e4, 1e6, 1e8];
/// Friction coefficients of the friction family.
pub const MUS: [f64; 6] = [0.0, 1e-4, 0.3, 1.0, 10.0, 1e3];
/// Unit factors of the scaling family (applied to length, mass and time in turn).
pub const UNIT_FACTORS: [f64; 4] = [1e-6, 1e-3, 1e3, 1e6];

/// Every case. `pile_size`: the granular pile's lattice (`nx, ny, nz`).
pub fn cases(pile_size: (usize, usize, usize)) -> Vec<Case> {
    let mut out = Vec::new();
    for r in RATIOS {
        out.push(case(
            format!("heavy-on-light-{r:e}"),
            "mass-ratio",
            &two_boxes(1.0, r, [0.3; 8], 0.1),
        ));
        out.push(case(
            format!("light-on-heavy-{r:e}"),
            "mass-ratio",
            &two_boxes(r, 1.0, [0.3; 8], 0.1),
        ));
        out.push(case(format!("chain-8-{r:e}"), "mass-ratio", &chain(8, r)));
    }
    for mu in MUS {
        // Pushed by half its weight: slides for mu < 0.5, sticks above.
        out.push(case(
            format!("box-mu-{mu:e}"),
            "friction",
            &box_pushed(mu, 0.5),
        ));
    }
    out.push(case(
        "mixed-mu",
        "friction",
        &two_boxes(1.0, 3.0, [0.0, 1e-4, 0.3, 1.0, 10.0, 1e3, 0.3, 0.0], 0.4),
    ));
    // Normal load 1e-3 N against a tangential force of 1e3 N: slides even with mu = 10.
    let mut s = Scene::default();
    let b = s.body(1.0, box_inertia(1.0, UNIT), [0.0, 0.0, 0.5]);
    s.bodies[b].force = [1e3, 0.0, -1e-3];
    s.contact(b, None, [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 10.0);
    out.push(case("light-load-slide-mu-10", "friction", &s));

    let base = tripod().global();
    out.push(units_case("units-base", &base, 1.0, 1.0, 1.0));
    for x in UNIT_FACTORS {
        out.push(units_case(
            &format!("units-length-{x:e}"),
            &base,
            x,
            1.0,
            1.0,
        ));
        out.push(units_case(&format!("units-mass-{x:e}"), &base, 1.0, x, 1.0));
        out.push(units_case(&format!("units-time-{x:e}"), &base, 1.0, 1.0, x));
    }

    // Four coplanar corners and an exact duplicate of each: H has rank 6 of 24.
    let mut s = box_pushed(0.3, 0.1);
    let dup = s.contacts.clone();
    s.contacts.extend(dup);
    out.push(case("redundant-duplicated-corners", "redundant", &s));

    // A rod along x lying on two points: inertia about its axis 1e-12 of the others.
    let mut s = Scene::default();
    let b = s.body(1.0, [1e-12 * 0.33, 0.33, 0.33], [0.0, 0.0, 0.01]);
    s.bodies[b].force[1] = 0.2 * GRAVITY;
    s.contact(b, None, [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.5);
    s.contact(b, None, [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.5);
    out.push(case("near-singular-inertia-1e-12", "inertia", &s));
    // A plank 100 m x 1 m x 1 mm on its four corners, pushed and twisted.
    let mut s = Scene::default();
    let size = [100.0, 1.0, 1e-3];
    let b = s.body(50.0, box_inertia(50.0, size), [0.0, 0.0, 5e-4]);
    s.bodies[b].force[1] = 0.2 * 50.0 * GRAVITY;
    s.bodies[b].torque[2] = 100.0;
    s.corners(b, None, size, [0.4; 4]);
    out.push(case("thin-long-plank", "inertia", &s));

    // 1000 contacts on one body: a 40 x 25 grid under a box, pushed sideways.
    let mut s = Scene::default();
    let b = s.body(10.0, box_inertia(10.0, [4.0, 2.5, 1.0]), [0.0, 0.0, 0.5]);
    s.bodies[b].force[0] = 0.2 * 10.0 * GRAVITY;
    for i in 0..40 {
        for j in 0..25 {
            let p = [-1.95 + 0.1 * i as f64, -1.2 + 0.1 * j as f64, 0.0];
            s.contact(b, None, p, [0.0, 0.0, 1.0], 0.3);
        }
    }
    out.push(case("one-body-1000-contacts", "many", &s));

    // A box landing at 1e3 m/s (and 10 m/s sideways) on its four corners.
    let mut s = box_pushed(0.3, 0.0);
    s.bodies[0].v = [10.0, 0.0, -1e3];
    out.push(case("impact-1e3", "impact", &s));

    // A box leaving the ground at 1 m/s: every contact separates, r = 0.
    let mut s = box_pushed(0.3, 0.0);
    s.bodies[0].v = [0.0, 0.0, 1.0];
    out.push(case("all-separating", "trivial", &s));

    let mut s = Scene::default();
    s.body(1.0, box_inertia(1.0, UNIT), [0.0, 0.0, 0.5]);
    out.push(case("zero-contacts", "trivial", &s));

    let mut s = Scene::default();
    let b = s.body(1.0, box_inertia(1.0, UNIT), [0.0, 0.0, 0.5]);
    s.bodies[b].force[0] = 1.0;
    s.contact(b, None, [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.3);
    out.push(case("one-contact", "trivial", &s));

    let (nx, ny, nz) = pile_size;
    let s = pile(nx, ny, nz);
    let name = format!("granular-pile-{}", s.contacts.len());
    out.push(case(name, "pile", &s));
    out
}

fn units_case(name: &str, base: &GlobalProblem, a: f64, b: f64, c: f64) -> Case {
    let global = scale_units(base, a, b, c);
    let local = Some(local_form(&global));
    Case {
        name: name.into(),
        family: "units",
        global,
        local,
    }
}

/// How one solve of one case ended, re-measured with `tests/common`.
pub struct Outcome {
    pub case: String,
    pub form: &'static str,
    pub variant: String,
    /// The status name, or `error: ...` when the solver refused the problem.
    pub status: String,
    /// The error measure recomputed independently of the library.
    pub error: f64,
    /// The library's own final error.
    pub reported_error: f64,
    pub iterations: usize,
    pub seconds: f64,
    /// Every component of the returned `r`, `u`, `v` is finite.
    pub finite: bool,
    pub solution: Solution,
}

/// Largest `n * 3nc` for which the dense independent measure is used (the sparse one above).
const DENSE_MAX: usize = 4_000_000;

/// Solves `case` in `form` (`global` or `local`) with `variant` at 1e-8.
pub fn run(
    case: &Case,
    form: &'static str,
    variant: &str,
    time_limit: f64,
    max_iterations: usize,
) -> Outcome {
    let problem = match form {
        "global" => Problem::Global(case.global.clone()),
        _ => Problem::Local(case.local.clone().expect("case has a local form")),
    };
    let settings = Settings {
        tolerance: 1e-8,
        time_limit,
        max_iterations,
        variant: VariantChoice::from_name(variant).expect("variant name"),
        ..Settings::default()
    };
    let t0 = Instant::now();
    let mut out = Outcome {
        case: case.name.clone(),
        form,
        variant: variant.to_string(),
        status: String::new(),
        error: f64::NAN,
        reported_error: f64::NAN,
        iterations: 0,
        seconds: 0.0,
        finite: true,
        solution: Solution::default(),
    };
    // Built without the time limit, which is set after: a solver built with one starts
    // with Gauss-Seidel sweeps (an engine's budget), and the limit here only keeps a
    // failing case from running on.
    let unlimited = Settings {
        time_limit: f64::INFINITY,
        ..settings.clone()
    };
    let solved = Solver::new(problem.clone(), unlimited).and_then(|mut s| {
        s.update_settings(settings)?;
        let status = s.solve()?;
        Ok((status, s))
    });
    out.seconds = t0.elapsed().as_secs_f64();
    match solved {
        Ok((status, solver)) => {
            let sol = solver.solution();
            out.status = status.name().to_string();
            out.iterations = solver.stats().iterations;
            out.reported_error = solver.stats().error;
            out.finite = sol
                .r
                .iter()
                .chain(&sol.u)
                .chain(&sol.v)
                .all(|x| x.is_finite());
            out.error = match &problem {
                Problem::Global(g) if g.n() * g.w.len() > DENSE_MAX => {
                    crate::common::global_error_sparse(g, &sol.r, &sol.v)
                }
                p => crate::common::error(p, &sol.r, &sol.v, &sol.lambda),
            };
            out.solution = sol.clone();
        }
        Err(e) => out.status = format!("error: {e}"),
    }
    out
}
