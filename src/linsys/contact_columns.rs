//! H stored contact by contact, for the matrix-free products. Where the three columns of
//! a contact have (nearly) one pattern, as a rigid body's contact rows do, they share one
//! list of velocity rows (the union of their patterns, a missing entry stored as a zero),
//! so that each index read and each velocity gathered serves three values. Where they do
//! not (an axis-aligned lattice: one entry per body in each column), the union would
//! store mostly zeros, and each column keeps its own rows.
//!
//! `H^T x` is a gather per contact. `H t` and the fused `H D H^T x` (one pass over H where
//! products by columns and by rows read it twice) scatter into the velocities in a fixed
//! split of the contacts into chunks, each chunk into its own buffer over the rows it
//! touches, the buffers then added in chunk order: each entry is summed in one order
//! whatever the number of threads that run the chunks.

use super::workers::Workers;
use crate::csc::CscMatrix;
use crate::tuning::{PARALLEL_MIN_ENTRIES, PRODUCT_CHUNKS, SHARED_ROWS_MAX_STORED};
use std::ops::Range;

/// A run of contacts, the velocity rows they touch and its scatter buffer over those rows
/// (unused when there is one chunk: it scatters into the output itself).
struct Chunk {
    contacts: Range<usize>,
    rows: Range<usize>,
    buffer: Vec<f64>,
}

/// The rows each contact's three columns of H touch together: contact `c`'s are
/// `rows[start[c]..start[c + 1]]`, ascending, and H's `k`-th stored entry (row `rows[a]`,
/// column `3 c + d`) has the slot `slot[k] = 3 a + d` in a row-major `rows x 3` layout of
/// the contacts' blocks ([`LEFT_OUT`] in a column not kept).
pub(crate) struct ContactRows {
    pub start: Vec<usize>,
    pub rows: Vec<usize>,
    pub slot: Vec<usize>,
}

/// The slot of an entry of H in a column [`ContactRows::of`] did not keep.
pub(crate) const LEFT_OUT: usize = usize::MAX;

impl ContactRows {
    /// The contacts of `h` (three columns each), over the columns `keep` accepts.
    pub fn of(h: &CscMatrix, keep: impl Fn(usize) -> bool) -> Self {
        let contacts = h.ncols() / 3;
        let (colptr, rowind) = (h.colptr(), h.rowind());
        let mut start = Vec::with_capacity(contacts + 1);
        start.push(0);
        let mut rows = Vec::with_capacity(h.nnz());
        let mut slot = vec![LEFT_OUT; h.nnz()];
        for c in 0..contacts {
            // The kept columns' rows (each sorted) merged: each entry learns its slot on
            // the way.
            let mut next: [usize; 3] = std::array::from_fn(|d| colptr[3 * c + d]);
            let end: [usize; 3] = std::array::from_fn(|d| {
                let k = 3 * c + d;
                colptr[if keep(k) { k + 1 } else { k }]
            });
            while let Some(low) = (0..3)
                .filter(|&d| next[d] < end[d])
                .map(|d| rowind[next[d]])
                .min()
            {
                for d in 0..3 {
                    if next[d] < end[d] && rowind[next[d]] == low {
                        slot[next[d]] = 3 * rows.len() + d;
                        next[d] += 1;
                    }
                }
                rows.push(low);
            }
            start.push(rows.len());
        }
        Self { start, rows, slot }
    }
}

/// The contact Jacobian `H` (velocities x 3 contacts), contact by contact.
pub(crate) struct ContactColumns {
    /// Shared rows: contact `c`'s rows are `rows[start[c]..start[c + 1]]`, ascending, and
    /// `values[3 k + d]` is H at row `rows[k]` and column `3 c + d`. Separate rows:
    /// column `j`'s entries are `start[j]..start[j + 1]` of `rows` and `values`.
    shared: bool,
    start: Vec<usize>,
    rows: Vec<u32>,
    values: Vec<f64>,
    /// Each stored entry of H: (its slot in `values`, its position in H's values).
    source: Vec<(usize, usize)>,
    chunks: Vec<Chunk>,
}

impl ContactColumns {
    /// Whether `h` can be stored so: three columns per contact, 32-bit row indices.
    pub fn fits(h: &CscMatrix) -> bool {
        h.ncols() % 3 == 0 && h.nrows() <= u32::MAX as usize
    }

    /// The contacts of `h` (which [`ContactColumns::fits`]).
    pub fn new(h: &CscMatrix) -> Self {
        let ContactRows {
            mut start,
            rows,
            slot,
        } = ContactRows::of(h, |_| true);
        let mut rows: Vec<u32> = rows.into_iter().map(|i| i as u32).collect();
        let mut source: Vec<(usize, usize)> = slot.into_iter().zip(0..).collect();
        let shared = 3 * rows.len() <= (SHARED_ROWS_MAX_STORED * h.nnz() as f64) as usize;
        if !shared {
            start = h.colptr().to_vec();
            rows = h.rowind().iter().map(|&i| i as u32).collect();
            source = (0..h.nnz()).map(|k| (k, k)).collect();
        }
        let contact_start: Vec<usize> = if shared {
            start.clone()
        } else {
            start.iter().step_by(3).copied().collect()
        };
        let mut columns = Self {
            values: vec![0.0; if shared { 3 * rows.len() } else { rows.len() }],
            chunks: chunks(&contact_start, &rows, h.nnz()),
            shared,
            start,
            rows,
            source,
        };
        columns.take_values(h);
        columns
    }

    /// Takes the values of `h` (the matrix it was made from, or one with its pattern).
    pub fn take_values(&mut self, h: &CscMatrix) {
        for &(at, k) in &self.source {
            self.values[at] = h.values()[k];
        }
    }

    /// Stored entries of H.
    pub fn entries(&self) -> usize {
        self.source.len()
    }

    /// `(H^T x)` for contact `c`.
    #[inline]
    fn gather(&self, c: usize, x: &[f64]) -> [f64; 3] {
        if !self.shared {
            return std::array::from_fn(|d| {
                let range = self.start[3 * c + d]..self.start[3 * c + d + 1];
                let values = &self.values[range.clone()];
                let rows = &self.rows[range];
                values
                    .iter()
                    .zip(rows)
                    .map(|(v, &i)| v * x[i as usize])
                    .sum()
            });
        }
        // Two running sums per column (one would wait on each addition: a contact's dozen
        // rows are then latency-bound); the order is fixed.
        let range = self.start[c]..self.start[c + 1];
        let rows = &self.rows[range.clone()];
        let values = &self.values[3 * range.start..3 * range.end];
        let (mut even, mut odd) = ([0.0; 3], [0.0; 3]);
        let (pairs, vpairs) = (rows.chunks_exact(2), values.chunks_exact(6));
        let (last, vlast) = (pairs.remainder(), vpairs.remainder());
        for (i, v) in pairs.zip(vpairs) {
            let (xa, xb) = (x[i[0] as usize], x[i[1] as usize]);
            for d in 0..3 {
                even[d] += v[d] * xa;
                odd[d] += v[3 + d] * xb;
            }
        }
        if let [i] = last {
            let xi = x[*i as usize];
            for d in 0..3 {
                even[d] += vlast[d] * xi;
            }
        }
        [even[0] + odd[0], even[1] + odd[1], even[2] + odd[2]]
    }

    /// `out = H^T x`, contact by contact (each entry is one gather, whatever the threads).
    pub fn mul_t(&self, x: &[f64], out: &mut [f64], workers: &Workers) {
        let per_part = (out.len() / 3).div_ceil(workers.count()).max(1);
        workers.run(out.chunks_mut(3 * per_part).enumerate(), |(k, part)| {
            for (c, t) in part.chunks_exact_mut(3).enumerate() {
                t.copy_from_slice(&self.gather(k * per_part + c, x));
            }
        });
    }

    /// `y += H t`.
    pub fn mul_add(&mut self, t: &[f64], y: &mut [f64], workers: &Workers) {
        let s = |_: &Self, c: usize| [t[3 * c], t[3 * c + 1], t[3 * c + 2]];
        self.scatter(y, workers, |_, _| {}, s);
    }

    /// `y = base + rho H D H^T x`, `D` the diagonal `active`, in one pass over H, where
    /// `base(first, part)` writes its part of `y` from `first` on (run beside the
    /// scatter).
    pub fn gram(
        &mut self,
        x: &[f64],
        active: &[f64],
        rho: f64,
        y: &mut [f64],
        workers: &Workers,
        base: impl Fn(usize, &mut [f64]) + Sync,
    ) {
        self.scatter(y, workers, base, |me, c| {
            let t = me.gather(c, x);
            let a = &active[3 * c..3 * c + 3];
            [rho * a[0] * t[0], rho * a[1] * t[1], rho * a[2] * t[2]]
        });
    }

    /// `y = base(y) + sum_c H_c s(c)`, chunk by chunk: with several chunks, each thread
    /// writes its share of `base` into `y` and scatters its chunks into their buffers,
    /// which are then added in chunk order.
    fn scatter(
        &mut self,
        y: &mut [f64],
        workers: &Workers,
        base: impl Fn(usize, &mut [f64]) + Sync,
        s: impl Fn(&Self, usize) -> [f64; 3] + Sync,
    ) {
        let mut chunks = std::mem::take(&mut self.chunks);
        if let [only] = chunks.as_slice() {
            base(0, y);
            self.scatter_into(only.contacts.clone(), y, 0, &s);
        } else {
            let me = &*self;
            let threads = workers.count();
            let (rows, groups) = (
                y.len().div_ceil(threads).max(1),
                chunks.len().div_ceil(threads),
            );
            // Part k: the k-th share of y and of the chunks (either may be empty).
            let mut shares = y.chunks_mut(rows);
            let mut runs = chunks.chunks_mut(groups);
            let parts = (0..threads).map(|k| (k, shares.next(), runs.next()));
            workers.run(parts, |(k, share, run)| {
                if let Some(share) = share {
                    base(k * rows, share);
                }
                for chunk in run.into_iter().flatten() {
                    chunk.buffer.fill(0.0);
                    me.scatter_into(
                        chunk.contacts.clone(),
                        &mut chunk.buffer,
                        chunk.rows.start,
                        &s,
                    );
                }
            });
            for chunk in &chunks {
                for (yi, b) in y[chunk.rows.clone()].iter_mut().zip(&chunk.buffer) {
                    *yi += b;
                }
            }
        }
        self.chunks = chunks;
    }

    /// `target[i - offset] += (H_c s(c))_i` over `contacts`.
    fn scatter_into(
        &self,
        contacts: Range<usize>,
        target: &mut [f64],
        offset: usize,
        s: &impl Fn(&Self, usize) -> [f64; 3],
    ) {
        for c in contacts {
            let t = s(self, c);
            if t == [0.0; 3] {
                continue;
            }
            if !self.shared {
                for (d, td) in t.iter().enumerate() {
                    let range = self.start[3 * c + d]..self.start[3 * c + d + 1];
                    for (&i, v) in self.rows[range.clone()].iter().zip(&self.values[range]) {
                        target[i as usize - offset] += v * td;
                    }
                }
                continue;
            }
            let range = self.start[c]..self.start[c + 1];
            for (&i, v) in self.rows[range.clone()]
                .iter()
                .zip(self.values[3 * range.start..3 * range.end].chunks_exact(3))
            {
                target[i as usize - offset] += v[0] * t[0] + v[1] * t[1] + v[2] * t[2];
            }
        }
    }
}

/// The fixed split of the contacts (contact `c`'s entries in `rows` from `start[c]`):
/// [`PRODUCT_CHUNKS`] runs of about equal entries for a matrix worth threads, one run below.
fn chunks(start: &[usize], rows: &[u32], entries: usize) -> Vec<Chunk> {
    let contacts = start.len() - 1;
    let count = if entries >= PARALLEL_MIN_ENTRIES {
        PRODUCT_CHUNKS.min(contacts).max(1)
    } else {
        1
    };
    let mut out = Vec::with_capacity(count);
    let mut first = 0;
    for k in 1..=count {
        // The first contact at or past k/count of the stored rows.
        let goal = rows.len() * k / count;
        let end = if k == count {
            contacts
        } else {
            start.partition_point(|&s| s < goal).clamp(first, contacts)
        };
        let touched = &rows[start[first]..start[end]];
        let lo = touched.iter().min().map_or(0, |&i| i as usize);
        let hi = touched.iter().max().map_or(0, |&i| i as usize + 1);
        out.push(Chunk {
            contacts: first..end,
            rows: lo..hi.max(lo),
            buffer: if count > 1 {
                vec![0.0; hi.max(lo) - lo]
            } else {
                Vec::new()
            },
        });
        first = end;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Random-looking H: with `aligned`, each column of a contact holds one entry per body
    /// on its own row (an axis-aligned lattice's pattern); without, the columns share most
    /// rows.
    fn h(contacts: usize, n: usize, aligned: bool) -> CscMatrix {
        let mut triplets = Vec::new();
        for c in 0..contacts {
            let (a, b) = ((7 * c + 3) % (n / 3), (13 * c + 5) % (n / 3));
            for d in 0..3 {
                let j = 3 * c + d;
                if aligned {
                    triplets.push((3 * a + d, j, 1.0 + (j % 5) as f64 * 0.25));
                    triplets.push((3 * b + d, j, -0.5 - (j % 3) as f64));
                    continue;
                }
                for r in 0..3 {
                    triplets.push((3 * a + r, j, 1.0 + ((j + r) % 5) as f64 * 0.25));
                    if d != 1 || r != 2 {
                        triplets.push((3 * b + r, j, -0.5 - ((j + r) % 3) as f64));
                    }
                }
            }
        }
        CscMatrix::from_triplets("H", n, 3 * contacts, &triplets).unwrap()
    }

    fn close(a: &[f64], b: &[f64]) {
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() <= 1e-12 * y.abs().max(1.0), "{x} vs {y}");
        }
    }

    /// Products against the compressed-column ones, in both layouts, with one chunk and
    /// with several, on 1 and 3 threads (bitwise equal to each other).
    #[test]
    fn products_match_the_compressed_columns() {
        let cases = [
            (9, 12, false),
            (9, 12, true),
            (40_000, 6_000, false),
            (40_000, 6_000, true),
        ];
        for (contacts, n, aligned) in cases {
            let h = h(contacts, n, aligned);
            let x: Vec<f64> = (0..n).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
            let t: Vec<f64> = (0..3 * contacts)
                .map(|j| ((j * 17) % 7) as f64 - 3.0)
                .collect();
            let active: Vec<f64> = (0..3 * contacts)
                .map(|j| (j / 3 % 4 != 0) as u8 as f64)
                .collect();
            let mut columns = ContactColumns::new(&h);
            assert_eq!(columns.chunks.len() > 1, h.nnz() >= PARALLEL_MIN_ENTRIES);
            assert_eq!(columns.shared, !aligned);

            let mut reference = vec![0.0; 3 * contacts];
            h.mul_t_vec(1.0, &x, 0.0, &mut reference);
            let mut ht = vec![0.0; n];
            h.mul_vec(1.0, &t, 0.0, &mut ht);
            let dhx: Vec<f64> = reference
                .iter()
                .zip(&active)
                .map(|(a, b)| 2.5 * a * b)
                .collect();
            let mut gram = vec![1.0; n];
            h.mul_vec(1.0, &dhx, 1.0, &mut gram);

            let as_bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            let mut runs = Vec::new();
            for workers in [Workers::serial(), Workers::new(3)] {
                let mut out = vec![0.0; 3 * contacts];
                columns.mul_t(&x, &mut out, &workers);
                close(&out, &reference);
                let mut y = vec![0.0; n];
                columns.mul_add(&t, &mut y, &workers);
                close(&y, &ht);
                let mut g = vec![f64::NAN; n];
                columns.gram(&x, &active, 2.5, &mut g, &workers, |_, part| part.fill(1.0));
                close(&g, &gram);
                runs.push([as_bits(&out), as_bits(&y), as_bits(&g)]);
            }
            assert!(runs[0] == runs[1], "threads changed a bit");
        }
    }
}
