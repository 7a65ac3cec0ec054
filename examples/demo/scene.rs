//! Rigid boxes, the container and collision detection of the demo.
//!
//! Box-plane contacts are the box corners; box-box contacts come from a separating axis
//! test: a face-face manifold (incident face clipped against the reference face) or one
//! edge-edge point.

use nalgebra::{Matrix3, UnitQuaternion, Vector3};

/// A 3-vector.
pub type V3 = Vector3<f64>;

/// A rigid box: pose, velocity (world frame) and mass properties.
#[derive(Clone, Debug)]
pub struct Body {
    /// Half extents along the body axes.
    pub half: V3,
    pub mass: f64,
    /// Principal moments of inertia (body frame).
    pub inertia: V3,
    pub pos: V3,
    pub rot: UnitQuaternion<f64>,
    pub vel: V3,
    pub omega: V3,
}

impl Body {
    pub fn new(half: V3, density: f64, pos: V3) -> Self {
        let mass = density * 8.0 * half.x * half.y * half.z;
        let (x2, y2, z2) = (half.x * half.x, half.y * half.y, half.z * half.z);
        Self {
            half,
            mass,
            inertia: V3::new(y2 + z2, x2 + z2, x2 + y2) * (mass / 3.0),
            pos,
            rot: UnitQuaternion::identity(),
            vel: V3::zeros(),
            omega: V3::zeros(),
        }
    }

    /// World-frame inertia tensor `R I R^T`, symmetrized against round-off (the solver
    /// factorizes M by Cholesky only when it is symmetric).
    pub fn inertia_world(&self) -> Matrix3<f64> {
        let r = self.rot.to_rotation_matrix().into_inner();
        let i = r * Matrix3::from_diagonal(&self.inertia) * r.transpose();
        (i + i.transpose()) * 0.5
    }

    fn axes(&self) -> [V3; 3] {
        let r = self.rot.to_rotation_matrix().into_inner();
        [r.column(0).into(), r.column(1).into(), r.column(2).into()]
    }

    /// Radius of the bounding sphere.
    pub fn extent(&self) -> f64 {
        self.half.norm()
    }

    /// Upper bound of the speed of any point of the body.
    pub fn max_point_speed(&self) -> f64 {
        self.vel.norm() + self.omega.norm() * self.extent()
    }

    pub fn kinetic_energy(&self) -> f64 {
        let i_omega = self.inertia_world() * self.omega;
        0.5 * self.mass * self.vel.norm_squared() + 0.5 * self.omega.dot(&i_omega)
    }

    /// Corners in world coordinates.
    pub fn vertices(&self) -> [V3; 8] {
        std::array::from_fn(|k| {
            let sign = |bit: usize| if k >> bit & 1 == 1 { 1.0 } else { -1.0 };
            let local = V3::new(
                sign(0) * self.half.x,
                sign(1) * self.half.y,
                sign(2) * self.half.z,
            );
            self.pos + self.rot * local
        })
    }

    /// Lowest value of `dir . x` over the body.
    pub fn support_min(&self, dir: &V3) -> f64 {
        self.vertices()
            .iter()
            .map(|v| dir.dot(v))
            .fold(f64::INFINITY, f64::min)
    }
}

/// A static half-space `normal . x >= offset` (normal pointing into the free side).
#[derive(Clone, Copy, Debug)]
pub struct Plane {
    pub name: &'static str,
    pub normal: V3,
    pub offset: f64,
}

/// The open-topped container: a floor at z = 0 and four walls at |x|, |y| = half_width.
pub fn container(half_width: f64) -> Vec<Plane> {
    let wall = |name, normal| Plane {
        name,
        normal,
        offset: -half_width,
    };
    vec![
        Plane {
            name: "floor",
            normal: V3::z(),
            offset: 0.0,
        },
        wall("wall -x", V3::x()),
        wall("wall +x", -V3::x()),
        wall("wall -y", V3::y()),
        wall("wall +y", -V3::y()),
    ]
}

/// What body `a` of a contact touches.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Partner {
    Plane(usize),
    /// Another body, always of a larger index than `a`.
    Body(usize),
}

/// One contact point. FCLib convention: the normal points from the partner B toward A,
/// so `u_N >= 0` means separating; `frame` holds the normal and two tangents as columns.
#[derive(Clone, Debug)]
pub struct Contact {
    pub a: usize,
    pub b: Partner,
    /// Midpoint of the two surface points.
    pub point: V3,
    pub frame: Matrix3<f64>,
    /// Signed distance (negative: penetration).
    pub gap: f64,
}

impl Contact {
    fn new(a: usize, b: Partner, point: V3, normal: V3, gap: f64) -> Self {
        // Body pairs are stored with a < b (one key per pair for warm starts).
        if let Partner::Body(j) = b {
            if j < a {
                return Self::new(j, Partner::Body(a), point, -normal, gap);
            }
        }
        // Any right-handed orthonormal tangent pair; warm starts go through the world
        // frame, so it need not be continuous in time.
        let helper = if normal.x.abs() < 0.6 {
            V3::x()
        } else {
            V3::y()
        };
        let t1 = normal.cross(&helper).normalize();
        let t2 = normal.cross(&t1);
        Self {
            a,
            b,
            point,
            frame: Matrix3::from_columns(&[normal, t1, t2]),
            gap,
        }
    }
}

/// All contacts whose gap is below `margin(a, b)` (b = None: a plane). The margin makes
/// them speculative: bodies approaching within one step are caught before they overlap.
pub fn detect(
    bodies: &[Body],
    planes: &[Plane],
    margin: impl Fn(usize, Option<usize>) -> f64,
) -> Vec<Contact> {
    let mut out = Vec::new();
    for (i, body) in bodies.iter().enumerate() {
        let limit = margin(i, None);
        for (k, plane) in planes.iter().enumerate() {
            // A convex polyhedron meets a plane at its corners first.
            for v in body.vertices() {
                let gap = plane.normal.dot(&v) - plane.offset;
                if gap < limit {
                    let p = v - plane.normal * (0.5 * gap);
                    out.push(Contact::new(i, Partner::Plane(k), p, plane.normal, gap));
                }
            }
        }
        for (j, other) in bodies.iter().enumerate().skip(i + 1) {
            let limit = margin(i, Some(j));
            if (body.pos - other.pos).norm() - body.extent() - other.extent() < limit {
                box_box(i, body, j, other, limit, &mut out);
            }
        }
    }
    out
}

/// Box A against box B by the separating axis test over the 15 candidate axes. On a face
/// axis, the most anti-parallel face of the other box is clipped against the reference
/// face (up to 8 points: how boxes rest on each other); on an edge-edge axis, one point
/// between the two closest edges.
fn box_box(a: usize, ba: &Body, b: usize, bb: &Body, limit: f64, out: &mut Vec<Contact>) {
    let (axes_a, axes_b) = (ba.axes(), bb.axes());
    let (ha, hb) = (ba.half, bb.half);
    let d = bb.pos - ba.pos;
    // Signed separation along a unit axis (negative: overlap).
    let separation = |l: &V3| {
        let reach_a: f64 = (0..3).map(|k| ha[k] * axes_a[k].dot(l).abs()).sum();
        let reach_b: f64 = (0..3).map(|k| hb[k] * axes_b[k].dot(l).abs()).sum();
        d.dot(l).abs() - reach_a - reach_b
    };
    // Best face axis: 0..3 on A, 3..6 on B.
    let mut face = (f64::NEG_INFINITY, 0);
    for k in 0..6 {
        let s = separation(&if k < 3 { axes_a[k] } else { axes_b[k - 3] });
        if s > face.0 {
            face = (s, k);
        }
    }
    let mut edge = (f64::NEG_INFINITY, 0, 0, V3::zeros());
    for (i, axis_a) in axes_a.iter().enumerate() {
        for (j, axis_b) in axes_b.iter().enumerate() {
            // Parallel edges give no axis (a face axis covers them).
            let c = axis_a.cross(axis_b);
            if c.norm() > 1e-6 {
                let l = c.normalize();
                let s = separation(&l);
                if s > edge.0 {
                    edge = (s, i, j, l);
                }
            }
        }
    }
    if face.0.max(edge.0) >= limit {
        return;
    }
    // Face contacts are preferred unless an edge axis separates clearly more.
    if edge.0 > face.0 + 1e-3 {
        let (gap, i, j, l) = edge;
        let toward_b = if d.dot(&l) > 0.0 { l } else { -l };
        // The edge of A furthest toward B and the edge of B furthest toward A.
        let (mut pa, mut pb) = (ba.pos, bb.pos);
        for k in 0..3 {
            if k != i {
                pa += axes_a[k] * (ha[k] * axes_a[k].dot(&toward_b).signum());
            }
            if k != j {
                pb -= axes_b[k] * (hb[k] * axes_b[k].dot(&toward_b).signum());
            }
        }
        let (ea, eb) = (axes_a[i], axes_b[j]);
        // Closest points of the segments pa + s ea and pb + t eb.
        let w = pa - pb;
        let c = ea.dot(&eb);
        let denom = (1.0 - c * c).max(1e-12);
        let s = ((c * eb.dot(&w) - ea.dot(&w)) / denom).clamp(-ha[i], ha[i]);
        let t = ((eb.dot(&w) - c * ea.dot(&w)) / denom).clamp(-hb[j], hb[j]);
        let p = 0.5 * (pa + ea * s + pb + eb * t);
        out.push(Contact::new(a, Partner::Body(b), p, -toward_b, gap));
        return;
    }
    // Reference face on body r, incident face on body o.
    let k = face.1;
    let (r, o, ref_axes, inc_axes, hr, ho, pr, po, axis) = if k < 3 {
        (a, b, &axes_a, &axes_b, ha, hb, ba.pos, bb.pos, k)
    } else {
        (b, a, &axes_b, &axes_a, hb, ha, bb.pos, ba.pos, k - 3)
    };
    // Reference face normal, from r toward o.
    let normal = ref_axes[axis] * (po - pr).dot(&ref_axes[axis]).signum();
    let inc = (0..3)
        .max_by(|&x, &y| {
            let dot = |k: usize| inc_axes[k].dot(&normal).abs();
            dot(x).total_cmp(&dot(y))
        })
        .expect("three axes");
    let inc_centre = po - inc_axes[inc] * (ho[inc] * inc_axes[inc].dot(&normal).signum());
    let (u, v) = ((inc + 1) % 3, (inc + 2) % 3);
    let mut polygon: Vec<V3> = [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)]
        .iter()
        .map(|(su, sv)| inc_centre + inc_axes[u] * (su * ho[u]) + inc_axes[v] * (sv * ho[v]))
        .collect();
    for side in (0..3).filter(|&s| s != axis) {
        for sign in [1.0, -1.0] {
            let dir = ref_axes[side] * sign;
            polygon = clip(&polygon, &dir, dir.dot(&pr) + hr[side]);
        }
    }
    let ref_plane = normal.dot(&pr) + hr[axis];
    for q in polygon {
        let gap = normal.dot(&q) - ref_plane;
        if gap < limit {
            let p = q - normal * (0.5 * gap);
            out.push(Contact::new(o, Partner::Body(r), p, normal, gap));
        }
    }
}

/// Sutherland-Hodgman: the part of a convex polygon with `dir . x <= bound`.
fn clip(polygon: &[V3], dir: &V3, bound: f64) -> Vec<V3> {
    let mut out = Vec::with_capacity(polygon.len() + 2);
    for (i, p) in polygon.iter().enumerate() {
        let q = &polygon[(i + 1) % polygon.len()];
        let (dp, dq) = (dir.dot(p) - bound, dir.dot(q) - bound);
        if dp <= 0.0 {
            out.push(*p);
        }
        // Strict crossings only: a vertex on the boundary is not emitted twice.
        if (dp < 0.0 && dq > 0.0) || (dp > 0.0 && dq < 0.0) {
            out.push(p + (q - p) * (dp / (dp - dq)));
        }
    }
    out
}
