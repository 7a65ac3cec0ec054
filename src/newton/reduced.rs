//! The global Newton system reduced to the velocities and joint multipliers.
//!
//! Each contact's rows of the Newton matrix, `A_i H_i^T dv + C_i dr_i = b_i` with the
//! regularized block `C_i = B_i + alpha A_i / rho_i`, give its impulse step
//! `dr_i = C_i^-1 b_i - E_i H_i^T dv` with `E_i = C_i^-1 A_i`. Substituted into the
//! velocity rows:
//!
//! ```text
//! [ M + H E H^T   -G      ] [ dv ]   [ b_v + H C^-1 b_r ]
//! [ G^T           alpha S ] [ dl ] = [ b_l              ]
//! ```
//!
//! a system of the size of the velocities with the pattern of ADMM's `M + H H^T`, where
//! the unreduced matrix carries three more rows per contact whose coupling through `A H^T`
//! fills the LU factors in under partial pivoting (docs/algorithms.md §9.4).
//!
//! On a sticking contact `E_i` is `rho_i / alpha` times the identity: the reduction is a
//! penalty form whose round-off in `dv` returns amplified in `dr`. Every solve is therefore
//! checked on the unreduced residual and refined with the same factors; one that does not
//! reach [`REDUCED_RESIDUAL`] is refused, and the caller solves the unreduced system.

use super::sparse::{Pattern, SparseLu};
use super::Mat3;
use crate::csc::CscMatrix;
use crate::linsys::ContactRows;
use crate::tuning::{REDUCED_REFINEMENTS, REDUCED_RESIDUAL};
use crate::types::Error;

/// The reduced Newton matrix, its factors and the per-contact eliminations of a step.
pub(super) struct ReducedSystem {
    n: usize,
    p: usize,
    lu: SparseLu,
    m_dest: Vec<usize>,
    g_dest: Vec<usize>,
    gt_dest: Vec<usize>,
    lam_dest: Vec<usize>,
    /// Per contact: where its rows (those of H in its three columns) start in the
    /// `h_local` blocks, `row_ptr[i]..row_ptr[i + 1]`.
    row_ptr: Vec<usize>,
    /// Per H entry (storage order): its place in `h_local`, the contact's rows x 3 block
    /// stored row-major from `3 row_ptr[i]`.
    h_pos: Vec<usize>,
    h_local: Vec<f64>,
    /// Per contact: positions of its `k x k` block of `H E H^T` (row-major, `k` its row
    /// count) in the matrix values, from `dest_ptr[i]`.
    dest: Vec<usize>,
    dest_ptr: Vec<usize>,
    /// Per contact: `C_i^-1` and `E_i = C_i^-1 A_i` of the current step.
    c_inv: Vec<Mat3>,
    e: Vec<Mat3>,
    /// Work: `C^-1 b_r`, `H^T dv`, the unreduced residual and a correction.
    y: Vec<f64>,
    ht: Vec<f64>,
    res: Vec<f64>,
    corr: Vec<f64>,
}

/// The problem's matrices and the step's Jacobian blocks, as the reduced system reads them.
pub(super) struct StepBlocks<'a> {
    pub m: &'a CscMatrix,
    pub h: &'a CscMatrix,
    pub g: Option<&'a CscMatrix>,
    pub a: &'a [Mat3],
    pub b: &'a [Mat3],
    /// `alpha / rho_i` per contact.
    pub reg: &'a [f64],
    /// The joint rows' diagonal: `alpha S_k + c_k`, or `S_k` for a row clamped at a bound.
    pub joint_reg: &'a [f64],
    /// Per joint row: clamped at a bound, its row then `S_k dl_k` alone (no `G^T`).
    pub clamped: &'a [bool],
}

impl ReducedSystem {
    /// Pattern, positions and symbolic analysis for `(M, H, G)` (`g` has `n` rows).
    pub fn new(m: &CscMatrix, h: &CscMatrix, g: &CscMatrix) -> Result<Self, Error> {
        let n = m.nrows();
        let p = g.ncols();
        let nc = h.ncols() / 3;
        let ContactRows {
            start: row_ptr,
            rows,
            slot: h_pos,
        } = ContactRows::of(h, |_| true);
        let contact_rows = |i: usize| &rows[row_ptr[i]..row_ptr[i + 1]];
        let mut cols: Vec<Vec<usize>> = vec![Vec::new(); n + p];
        for c in 0..m.ncols() {
            cols[c].extend(m.col(c).map(|(i, _)| i));
        }
        for k in 0..p {
            for (j, _) in g.col(k) {
                cols[j].push(n + k);
                cols[n + k].push(j);
            }
            cols[n + k].push(n + k);
        }
        for i in 0..nc {
            let r = contact_rows(i);
            for &j in r {
                cols[j].extend_from_slice(r);
            }
        }
        let pat = Pattern::from_columns(n + p, cols);
        let mut dest = Vec::new();
        let mut dest_ptr = Vec::with_capacity(nc + 1);
        dest_ptr.push(0);
        for i in 0..nc {
            let r = contact_rows(i);
            for &row in r {
                dest.extend(r.iter().map(|&col| pat.pos(row, col)));
            }
            dest_ptr.push(dest.len());
        }
        let m_dest = (0..m.ncols())
            .flat_map(|c| m.col(c).map(move |(i, _)| (i, c)))
            .map(|(i, c)| pat.pos(i, c))
            .collect();
        let g_entries = || (0..p).flat_map(|k| g.col(k).map(move |(j, _)| (j, k)));
        let g_dest = g_entries().map(|(j, k)| pat.pos(j, n + k)).collect();
        let gt_dest = g_entries().map(|(j, k)| pat.pos(n + k, j)).collect();
        let lam_dest = (0..p).map(|k| pat.pos(n + k, n + k)).collect();
        let h_local = vec![0.0; 3 * rows.len()];
        Ok(Self {
            n,
            p,
            lu: SparseLu::new("reduced Newton matrix", pat)?,
            m_dest,
            g_dest,
            gt_dest,
            lam_dest,
            row_ptr,
            h_pos,
            h_local,
            dest,
            dest_ptr,
            c_inv: vec![[[0.0; 3]; 3]; nc],
            e: vec![[[0.0; 3]; 3]; nc],
            y: vec![0.0; 3 * nc],
            ht: vec![0.0; 3 * nc],
            res: vec![0.0; n + p + 3 * nc],
            corr: vec![0.0; n + p + 3 * nc],
        })
    }

    /// Numeric factorizations done.
    pub fn factorizations(&self) -> usize {
        self.lu.factorizations()
    }

    /// Eliminates every contact and factorizes; false when a contact block or the reduced
    /// matrix is singular.
    pub fn factor(&mut self, s: &StepBlocks) -> bool {
        for i in 0..self.c_inv.len() {
            let mut c = s.b[i];
            for (row, a_row) in c.iter_mut().zip(&s.a[i]) {
                for (x, a) in row.iter_mut().zip(a_row) {
                    *x += s.reg[i] * a;
                }
            }
            match inverse(&c) {
                Some(inv) => {
                    self.e[i] = mul3(&inv, &s.a[i]);
                    self.c_inv[i] = inv;
                }
                None => return false,
            }
        }
        for (k, &v) in s.h.values().iter().enumerate() {
            self.h_local[self.h_pos[k]] = v;
        }
        let vals = &mut self.lu.values;
        vals.fill(0.0);
        for (k, &v) in s.m.values().iter().enumerate() {
            vals[self.m_dest[k]] = v;
        }
        if let Some(g) = s.g {
            for ((entry, &v), col) in g.values().iter().enumerate().zip(columns(g)) {
                vals[self.g_dest[entry]] = -v;
                vals[self.gt_dest[entry]] = if s.clamped[col] { 0.0 } else { v };
            }
        }
        for (&d, &reg) in self.lam_dest.iter().zip(s.joint_reg) {
            vals[d] = reg;
        }
        for (i, e) in self.e.iter().enumerate() {
            let (lo, hi) = (self.row_ptr[i], self.row_ptr[i + 1]);
            let k = hi - lo;
            let hl = &self.h_local[3 * lo..3 * hi];
            let dest = &self.dest[self.dest_ptr[i]..self.dest_ptr[i + 1]];
            for a in 0..k {
                // Row a of H_i E_i, then its products with every row b of H_i.
                let ha = &hl[3 * a..3 * a + 3];
                let he: [f64; 3] =
                    std::array::from_fn(|q| ha[0] * e[0][q] + ha[1] * e[1][q] + ha[2] * e[2][q]);
                for b in 0..k {
                    let hb = &hl[3 * b..3 * b + 3];
                    vals[dest[a * k + b]] += he[0] * hb[0] + he[1] * hb[1] + he[2] * hb[2];
                }
            }
        }
        self.lu.factor()
    }

    /// Solves the unreduced Newton system for the right-hand side `rhs = (b_v, b_l, b_r)`
    /// into `d`, refining on the unreduced residual; false when the solve is not finite or
    /// does not reach [`REDUCED_RESIDUAL`] relative to `rhs`.
    pub fn solve(&mut self, s: &StepBlocks, rhs: &[f64], d: &mut [f64]) -> bool {
        let scale = crate::csc::dot(rhs, rhs).sqrt();
        d.fill(0.0);
        let mut res = std::mem::take(&mut self.res);
        let mut corr = std::mem::take(&mut self.corr);
        res.copy_from_slice(rhs);
        let mut ok = false;
        for _ in 0..=REDUCED_REFINEMENTS {
            if !self.solve_once(s, &res, &mut corr) {
                break;
            }
            for (x, c) in d.iter_mut().zip(&corr) {
                *x += c;
            }
            self.residual(s, rhs, d, &mut res);
            let norm = crate::csc::dot(&res, &res).sqrt();
            if !norm.is_finite() {
                break;
            }
            if norm <= REDUCED_RESIDUAL * scale {
                ok = true;
                break;
            }
        }
        self.res = res;
        self.corr = corr;
        ok
    }

    /// One solve through the reduced factors: `J^-1 b` up to the reduction's round-off.
    fn solve_once(&mut self, s: &StepBlocks, b: &[f64], d: &mut [f64]) -> bool {
        let np = self.n + self.p;
        let (d_vl, d_r) = d.split_at_mut(np);
        for (i, c_inv) in self.c_inv.iter().enumerate() {
            let bi = &b[np + 3 * i..np + 3 * i + 3];
            for (row, y) in c_inv.iter().zip(&mut self.y[3 * i..3 * i + 3]) {
                *y = row[0] * bi[0] + row[1] * bi[1] + row[2] * bi[2];
            }
        }
        d_vl.copy_from_slice(&b[..np]);
        s.h.mul_vec(1.0, &self.y, 1.0, &mut d_vl[..self.n]);
        if !self.lu.solve_in_place(d_vl) {
            return false;
        }
        s.h.mul_t_vec(1.0, &d_vl[..self.n], 0.0, &mut self.ht);
        for (i, e) in self.e.iter().enumerate() {
            let t = &self.ht[3 * i..3 * i + 3];
            for q in 0..3 {
                d_r[3 * i + q] =
                    self.y[3 * i + q] - (e[q][0] * t[0] + e[q][1] * t[1] + e[q][2] * t[2]);
            }
        }
        true
    }

    /// `res = rhs - J d` for the unreduced Newton matrix `J`.
    fn residual(&mut self, s: &StepBlocks, rhs: &[f64], d: &[f64], res: &mut [f64]) {
        let (n, p) = (self.n, self.p);
        let (dv, dl, dr) = (&d[..n], &d[n..n + p], &d[n + p..]);
        res.copy_from_slice(rhs);
        let (rv, rest) = res.split_at_mut(n);
        let (rl, rr) = rest.split_at_mut(p);
        s.m.mul_vec(-1.0, dv, 1.0, rv);
        s.h.mul_vec(1.0, dr, 1.0, rv);
        if let Some(g) = s.g {
            g.mul_vec(1.0, dl, 1.0, rv);
            g.mul_t_vec(-1.0, dv, 1.0, rl);
            for k in (0..p).filter(|&k| s.clamped[k]) {
                // A clamped row has no G^T: take its product back out.
                rl[k] += g.col(k).map(|(i, x)| x * dv[i]).sum::<f64>();
            }
        }
        for ((x, l), reg) in rl.iter_mut().zip(dl).zip(s.joint_reg) {
            *x -= reg * l;
        }
        s.h.mul_t_vec(1.0, dv, 0.0, &mut self.ht);
        for i in 0..self.e.len() {
            let (a, b, reg) = (&s.a[i], &s.b[i], s.reg[i]);
            let t = &self.ht[3 * i..3 * i + 3];
            let x = &dr[3 * i..3 * i + 3];
            for q in 0..3 {
                let mut v = 0.0;
                for k in 0..3 {
                    v += a[q][k] * (t[k] + reg * x[k]) + b[q][k] * x[k];
                }
                rr[3 * i + q] -= v;
            }
        }
    }
}

/// The column of each stored entry of `a`, in storage order.
pub(super) fn columns(a: &CscMatrix) -> impl Iterator<Item = usize> + '_ {
    (0..a.ncols()).flat_map(|k| std::iter::repeat_n(k, a.col(k).count()))
}

fn mul3(a: &Mat3, b: &Mat3) -> Mat3 {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

/// Inverse of a 3 x 3 matrix by cofactors; `None` when singular or not finite.
fn inverse(c: &Mat3) -> Option<Mat3> {
    let cof = |i: usize, j: usize| {
        let (r0, r1) = ((i + 1) % 3, (i + 2) % 3);
        let (c0, c1) = ((j + 1) % 3, (j + 2) % 3);
        c[r0][c0] * c[r1][c1] - c[r0][c1] * c[r1][c0]
    };
    let det = c[0][0] * cof(0, 0) + c[0][1] * cof(0, 1) + c[0][2] * cof(0, 2);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv: Mat3 = std::array::from_fn(|i| std::array::from_fn(|j| cof(j, i) / det));
    inv.iter().flatten().all(|x| x.is_finite()).then_some(inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_of_a_3x3_block() {
        let c = [[2.0, 1.0, 0.0], [0.5, 3.0, 1.0], [0.0, -1.0, 4.0]];
        let inv = inverse(&c).unwrap();
        let id = mul3(&c, &inv);
        for (i, row) in id.iter().enumerate() {
            for (j, &x) in row.iter().enumerate() {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((x - want).abs() < 1e-14, "{i} {j}: {x}");
            }
        }
        assert!(inverse(&[[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 0.0, 1.0]]).is_none());
    }
}
