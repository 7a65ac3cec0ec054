//! The v-update system `M + rho H D H^T` of a distributed problem, solved by the same
//! preconditioned conjugate gradients as one process's iterative backend
//! ([`crate::linsys::GramPcg`]): each process applies its own bodies' `M` and its own
//! contacts' `H` (after [`Halo::share`]: their copies of other processes' velocities),
//! and [`Halo::gather_back`] hands each owner what the others added to its velocities.
//! The block-Jacobi preconditioner is each owned body's block of the whole system,
//! contacts of every process included.

use super::halo::{agree, agree_on, Halo};
use super::problem::{RankError, RankProblem};
use crate::csc::{dot, CscMatrix};
use crate::linsys::{
    conjugate_gradients, BlockDiagonal, CgSystem, CgWork, ContactColumns, PcgOutcome, PcgStop,
    Workers, BLOCK_MAX,
};
use crate::types::ErrorKind;
use mpi::topology::SimpleCommunicator;
use std::time::Instant;

/// `M + rho H D H^T` over the processes sharing a problem, with its preconditioner.
pub(crate) struct DistributedGram {
    halo: Halo,
    /// This process's contacts' columns of H, over its vectors (owned velocities, copies).
    h: ContactColumns,
    /// Owned bodies: first velocity, velocities, and the offset of their dense blocks (in
    /// the part's mass, as in `mass` and `gram`).
    blocks: Vec<(usize, usize, usize)>,
    /// The owned bodies' mass blocks (symmetric part) and the inverses of
    /// `M_BB + rho (H D H^T)_BB`.
    mass: BlockDiagonal,
    /// `(H D H^T)_BB` of every process's contacts, laid out as the mass blocks.
    gram: Vec<f64>,
    active: Vec<f64>,
    rho: f64,
    serial: Workers,
    /// Vectors over owned velocities and copies, for the products.
    x_local: Vec<f64>,
    y_local: Vec<f64>,
    work: CgWork,
}

impl DistributedGram {
    /// The system of `part`, this process's part of a problem shared over `comm` (every
    /// process calls it with its own part); `active` marks the contact rows in it.
    pub fn new(
        comm: &SimpleCommunicator,
        part: &RankProblem,
        active: Vec<f64>,
    ) -> Result<Self, RankError> {
        agree_on(comm, part.validate())?;
        let touched = part.h_body.iter().copied().enumerate();
        let halo = Halo::new(comm, &part.bodies, &part.dofs, touched)?;
        let h = local_h(&halo, part);
        agree(comm, h.as_ref().err().cloned())?;
        let h = h.expect("agreed");
        let mut blocks = Vec::with_capacity(part.bodies.len());
        let (mut first, mut offset) = (0, 0);
        for &k in &part.dofs {
            blocks.push((first, k, offset));
            first += k;
            offset += k * k;
        }
        let mut mass = BlockDiagonal::consecutive(&part.dofs);
        mass.matrix_mut().copy_from_slice(&part.mass);
        mass.symmetrize();
        let local = halo.local();
        let owned = halo.owned();
        Ok(Self {
            gram: block_gram(&halo, &h, &active, &blocks),
            h: ContactColumns::new(&h),
            halo,
            blocks,
            mass,
            active,
            rho: f64::NAN,
            serial: Workers::serial(),
            x_local: vec![0.0; local],
            y_local: vec![0.0; local],
            work: CgWork::new(owned),
        })
    }

    /// Factorizes the owned blocks of `M + rho H D H^T`; every process gets the error
    /// when one block is not positive definite.
    pub fn set_rho(&mut self, rho: f64) -> Result<(), RankError> {
        let failed = self.mass.invert(rho, &self.gram).err();
        agree(
            self.halo.comm(),
            failed.map(|b| {
                (
                    ErrorKind::NotPositiveDefinite,
                    format!("bodies[{b}]: M + rho H H^T is not positive definite"),
                )
            }),
        )?;
        self.rho = rho;
        Ok(())
    }

    /// Solves the system for `x` (owned velocities) from the `x` given, until `stop`.
    pub fn solve(&mut self, b: &[f64], x: &mut [f64], stop: &PcgStop) -> PcgOutcome {
        let mut work = std::mem::take(&mut self.work);
        work.start(self, b, x);
        let out = conjugate_gradients(self, x, &mut work, stop);
        self.work = work;
        out
    }
}

impl DistributedGram {
    /// Owned bodies: first velocity, velocities, and the offset of their dense blocks.
    pub fn blocks(&self) -> &[(usize, usize, usize)] {
        &self.blocks
    }

    /// The exchange plan (for the sums of the solve around the system).
    pub fn halo(&self) -> &Halo {
        &self.halo
    }

    /// `out = H t` over the owned velocities (`t` over this process's contact rows): the
    /// other processes' contributions to owned bodies added in.
    pub fn h_mul(&mut self, t: &[f64], out: &mut [f64]) {
        self.y_local.fill(0.0);
        self.h.mul_add(t, &mut self.y_local, &self.serial);
        self.halo.gather_back(&mut self.y_local);
        out.copy_from_slice(&self.y_local[..out.len()]);
    }

    /// `out = H^T v` over this process's contact rows, from the owned velocities `v`
    /// (the copies fetched from their owners).
    pub fn h_t_mul(&mut self, v: &[f64], out: &mut [f64]) {
        self.x_local[..v.len()].copy_from_slice(v);
        self.halo.share(&mut self.x_local);
        self.h.mul_t(&self.x_local, out, &self.serial);
    }
}

impl CgSystem for DistributedGram {
    fn apply(&mut self, x: &[f64], y: &mut [f64]) {
        let owned = x.len();
        self.x_local[..owned].copy_from_slice(x);
        self.halo.share(&mut self.x_local);
        let (mass, x_local) = (&self.mass, &self.x_local);
        // The products run on this thread alone (`serial`): `part` is the whole vector.
        let mass_product = |first: usize, part: &mut [f64]| {
            debug_assert_eq!((first, part.len()), (0, x_local.len()));
            let (owned_part, copies) = part.split_at_mut(owned);
            mass.mul(x_local, owned_part);
            copies.fill(0.0);
        };
        self.h.gram(
            &self.x_local,
            &self.active,
            self.rho,
            &mut self.y_local,
            &self.serial,
            mass_product,
        );
        self.halo.gather_back(&mut self.y_local);
        y.copy_from_slice(&self.y_local[..owned]);
    }

    fn precondition(&self, r: &[f64], z: &mut [f64]) {
        self.mass.mul_inverse(0..self.mass.block_count(), r, z);
    }

    fn dot(&self, a: &[f64], b: &[f64]) -> f64 {
        let mut sum = [dot(a, b)];
        self.halo.sum_across(&mut sum);
        sum[0]
    }

    fn past(&self, deadline: Instant) -> bool {
        let mut late = [f64::from(u8::from(Instant::now() >= deadline))];
        self.halo.sum_across(&mut late);
        late[0] > 0.0
    }
}

/// This process's contacts' H over its vectors, or what is wrong in it.
fn local_h(halo: &Halo, part: &RankProblem) -> Result<CscMatrix, (ErrorKind, String)> {
    let mut rows = Vec::with_capacity(part.h_body.len());
    for (e, (&id, &dof)) in part.h_body.iter().zip(&part.h_dof).enumerate() {
        let place = halo.place(id);
        if dof >= place.dofs {
            return Err((
                ErrorKind::InvalidValue,
                format!(
                    "h_dof[{e}]: velocity {dof} of body id {id}, which has {}",
                    place.dofs
                ),
            ));
        }
        rows.push(place.first + dof);
    }
    CscMatrix::new(
        "H",
        halo.local(),
        3 * part.n_contacts(),
        part.h_colptr.clone(),
        rows,
        part.h_values.clone(),
    )
    .map_err(|e| (e.kind(), e.to_string()))
}

/// `(H D H^T)_BB` of every body this process owns (`blocks`: first velocity, velocities,
/// offset of its column-major block), all processes' contacts added: accumulated per
/// velocity `i` of a body starting at `first` in `BLOCK_MAX` entries whose `j`-th is the
/// entry `(first + j, i)`, over owned and copied bodies, copies handed back to owners.
fn block_gram(
    halo: &Halo,
    h: &CscMatrix,
    active: &[f64],
    blocks: &[(usize, usize, usize)],
) -> Vec<f64> {
    // The body (first velocity) of each velocity in this process's vectors.
    let mut body_first = vec![0; halo.local()];
    for place in halo.layout() {
        body_first[place.first..place.first + place.dofs].fill(place.first);
    }
    let mut columns = vec![0.0; BLOCK_MAX * halo.local()];
    for c in 0..h.ncols() {
        if active[c] == 0.0 {
            continue;
        }
        for (i, a) in h.col(c) {
            for (j, b) in h.col(c) {
                if body_first[i] == body_first[j] {
                    columns[BLOCK_MAX * i + (j - body_first[i])] += a * b;
                }
            }
        }
    }
    halo.gather_back_wide(&mut columns, BLOCK_MAX);
    let mut gram = Vec::with_capacity(blocks.iter().map(|&(_, k, _)| k * k).sum());
    for &(first, k, _) in blocks {
        for column in columns[BLOCK_MAX * first..].chunks_exact(BLOCK_MAX).take(k) {
            gram.extend_from_slice(&column[..k]);
        }
    }
    gram
}

#[cfg(test)]
mod tests {
    //! Each test runs itself again on several processes ([`crate::distributed::mpirun`]);
    //! the parent checks the exit codes and what the processes printed.
    use super::*;
    use crate::distributed::mpirun;
    use mpi::traits::Communicator;
    use nalgebra::{DMatrix, DVector};

    /// A pile of spheres on a jittered `nx x ny x nz` grid: contacts between neighbours
    /// along each axis and with the floor under the lowest layer. Per body: id, grid x
    /// index, mass; per contact: the two bodies (the second absent at the floor) and the
    /// three columns of each body's block of H (6 entries each).
    struct Pile {
        bodies: Vec<(u64, usize, f64)>,
        contacts: Vec<(usize, Option<usize>, Block, Block)>,
    }

    /// A body's three columns of a contact's H block, six velocities each.
    type Block = [[f64; 6]; 3];

    fn pile(nx: usize, ny: usize, nz: usize) -> Pile {
        let mut seed = 12345u64;
        let mut rand = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let index = |x: usize, y: usize, z: usize| (z * ny + y) * nx + x;
        let mut bodies = Vec::new();
        let mut centre = Vec::new();
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let id = 1000 + 7 * index(x, y, z) as u64;
                    bodies.push((id, x, 0.5 + 1.5 * rand()));
                    let jitter = [0.1 * rand(), 0.1 * rand(), 0.1 * rand()];
                    centre.push([
                        x as f64 + jitter[0],
                        y as f64 + jitter[1],
                        z as f64 + jitter[2],
                    ]);
                }
            }
        }
        let block = |arm: [f64; 3], frame: [[f64; 3]; 3], sign: f64| {
            frame.map(|d| {
                let t = [
                    arm[1] * d[2] - arm[2] * d[1],
                    arm[2] * d[0] - arm[0] * d[2],
                    arm[0] * d[1] - arm[1] * d[0],
                ];
                [d[0], d[1], d[2], t[0], t[1], t[2]].map(|v| sign * v)
            })
        };
        let frame = |n: [f64; 3]| {
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let n = n.map(|v| v / len);
            let a = if n[0].abs() < 0.9 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            };
            let t1 = [
                n[1] * a[2] - n[2] * a[1],
                n[2] * a[0] - n[0] * a[2],
                n[0] * a[1] - n[1] * a[0],
            ];
            let l1 = (t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]).sqrt();
            let t1 = t1.map(|v| v / l1);
            let t2 = [
                n[1] * t1[2] - n[2] * t1[1],
                n[2] * t1[0] - n[0] * t1[2],
                n[0] * t1[1] - n[1] * t1[0],
            ];
            [n, t1, t2]
        };
        let mut contacts = Vec::new();
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let a = index(x, y, z);
                    if z == 0 {
                        let f = frame([0.0, 0.0, 1.0]);
                        contacts.push((a, None, block([0.0, 0.0, -0.5], f, 1.0), [[0.0; 6]; 3]));
                    }
                    for (dx, dy, dz) in [(1, 0, 0), (0, 1, 0), (0, 0, 1)] {
                        if x + dx < nx && y + dy < ny && z + dz < nz {
                            let b = index(x + dx, y + dy, z + dz);
                            let n: [f64; 3] = std::array::from_fn(|k| centre[b][k] - centre[a][k]);
                            let f = frame(n);
                            let half = f[0].map(|v| 0.5 * v);
                            contacts.push((
                                a,
                                Some(b),
                                block(half, f, -1.0),
                                block(half.map(|v| -v), f, 1.0),
                            ));
                        }
                    }
                }
            }
        }
        Pile { bodies, contacts }
    }

    /// The part of `pile` the process `rank` of `size` owns: the bodies of its slab of x
    /// indices, and the contacts whose first body it owns.
    fn part(pile: &Pile, nx: usize, rank: usize, size: usize) -> RankProblem {
        let owner = |b: usize| pile.bodies[b].1 * size / nx;
        let mut p = RankProblem {
            h_colptr: vec![0],
            ..Default::default()
        };
        for (b, &(id, _, m)) in pile.bodies.iter().enumerate() {
            if owner(b) != rank {
                continue;
            }
            p.bodies.push(id);
            p.dofs.push(6);
            let inertia = 0.1 * m;
            for j in 0..6 {
                for i in 0..6 {
                    p.mass.push(if i != j {
                        0.0
                    } else if i < 3 {
                        m
                    } else {
                        inertia
                    });
                }
            }
            p.f.extend((0..6).map(|k| ((id as f64) * 0.37 + k as f64).sin()));
        }
        for (a, b, block_a, block_b) in &pile.contacts {
            if owner(*a) != rank {
                continue;
            }
            for d in 0..3 {
                for (body, block) in [(Some(*a), block_a), (*b, block_b)] {
                    let Some(body) = body else { continue };
                    for (dof, &v) in block[d].iter().enumerate() {
                        p.h_body.push(pile.bodies[body].0);
                        p.h_dof.push(dof);
                        p.h_values.push(v);
                    }
                }
                p.h_colptr.push(p.h_body.len());
            }
            p.w.extend([0.0; 3]);
            p.mu.push(0.3);
        }
        p
    }

    /// `(M + rho H H^T) x = f` of the whole pile, solved densely (nalgebra's Cholesky).
    fn reference(pile: &Pile, nx: usize, rho: f64) -> Vec<f64> {
        let whole = part(pile, nx, 0, 1);
        let n = whole.n_velocities();
        let at: std::collections::HashMap<u64, usize> = whole
            .bodies
            .iter()
            .enumerate()
            .map(|(b, &id)| (id, 6 * b))
            .collect();
        let mut a = DMatrix::<f64>::zeros(n, n);
        for (b, _) in whole.bodies.iter().enumerate() {
            for j in 0..6 {
                for i in 0..6 {
                    a[(6 * b + i, 6 * b + j)] = whole.mass[36 * b + 6 * j + i];
                }
            }
        }
        for c in 0..3 * whole.n_contacts() {
            let column = whole.h_colptr[c]..whole.h_colptr[c + 1];
            let row = |e: usize| at[&whole.h_body[e]] + whole.h_dof[e];
            for e in column.clone() {
                for f in column.clone() {
                    a[(row(e), row(f))] += rho * whole.h_values[e] * whole.h_values[f];
                }
            }
        }
        let x = a
            .cholesky()
            .expect("positive definite")
            .solve(&DVector::from_vec(whole.f.clone()));
        x.as_slice().to_vec()
    }

    #[test]
    fn every_process_count_solves_the_whole_system() {
        let name = "distributed::system::tests::every_process_count_solves_the_whole_system";
        if !mpirun::is_child() {
            for np in [1, 2, 4] {
                let out = mpirun::run(name, np, &[]);
                assert_eq!(
                    out.matches("agrees with the one-process solve").count(),
                    np,
                    "{out}"
                );
            }
            // Bitwise the same from run to run at a given number of processes.
            let checksums = |out: String| -> Vec<String> {
                let mut lines: Vec<String> = out
                    .lines()
                    .filter(|l| l.contains("checksum"))
                    .map(String::from)
                    .collect();
                lines.sort();
                lines
            };
            let run = || checksums(mpirun::run(name, 2, &[]));
            let (first, second) = (run(), run());
            assert_eq!(first.len(), 2);
            assert_eq!(first, second);
            return;
        }
        let universe = mpi::initialize().expect("MPI starts");
        let world = universe.world();
        let (rank, size) = (world.rank() as usize, world.size() as usize);
        let (nx, rho) = (8, 0.7);
        let pile = pile(nx, 4, 4);
        let mine = part(&pile, nx, rank, size);
        let mut system =
            DistributedGram::new(&world, &mine, vec![1.0; 3 * mine.n_contacts()]).expect("valid");
        system.set_rho(rho).expect("positive definite");
        let mut x = vec![0.0; mine.n_velocities()];
        let stop = PcgStop {
            tol: 0.0,
            reduction: 1e-13,
            floor: 0.0,
            max_iterations: 1000,
            deadline: None,
        };
        let outcome = system.solve(&mine.f, &mut x, &stop);
        assert!(outcome.converged, "{outcome:?}");
        // The reference, at this process's bodies.
        let whole = reference(&pile, nx, rho);
        let all_ids: Vec<u64> = pile.bodies.iter().map(|b| b.0).collect();
        let mut worst: f64 = 0.0;
        for (b, id) in mine.bodies.iter().enumerate() {
            let at = 6 * all_ids.iter().position(|i| i == id).expect("a pile body");
            for k in 0..6 {
                worst = worst.max((x[6 * b + k] - whole[at + k]).abs());
            }
        }
        let scale = whole.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(
            worst <= 1e-9 * scale,
            "rank {rank}: off by {worst:e} (scale {scale:e})"
        );
        let bits = x.iter().fold(0u64, |h, v| h.rotate_left(5) ^ v.to_bits());
        println!(
            "rank {rank}: {} iterations, agrees with the one-process solve",
            outcome.iterations
        );
        println!("rank {rank} checksum {bits:016x}");
    }

    #[test]
    fn a_bad_part_is_every_process_error() {
        let name = "distributed::system::tests::a_bad_part_is_every_process_error";
        if !mpirun::is_child() {
            let out = mpirun::run(name, 2, &[]);
            assert_eq!(out.matches("same error").count(), 4, "{out}");
            return;
        }
        let universe = mpi::initialize().expect("MPI starts");
        let world = universe.world();
        let (rank, size) = (world.rank() as usize, world.size() as usize);
        let pile = pile(4, 2, 2);
        // Rank 1 names a body no process owns; then rank 0 hands a NaN.
        let mut mine = part(&pile, 4, rank, size);
        if rank == 1 {
            mine.h_body[4] = 999_999;
        }
        let active = vec![1.0; 3 * mine.n_contacts()];
        let error = DistributedGram::new(&world, &mine, active.clone())
            .err()
            .expect("an error");
        assert_eq!((error.rank, error.kind), (1, ErrorKind::InvalidValue));
        assert_eq!(
            error.message,
            "h_body[4]: body id 999999 is owned by no process"
        );
        println!("rank {rank}: same error: {error}");
        let mut mine = part(&pile, 4, rank, size);
        if rank == 0 {
            mine.f[3] = f64::NAN;
        }
        let error = DistributedGram::new(&world, &mine, active)
            .err()
            .expect("an error");
        assert_eq!((error.rank, error.kind), (0, ErrorKind::InvalidValue));
        assert!(
            error.message.contains("f") && error.message.contains('3'),
            "{error}"
        );
        println!("rank {rank}: same error: {error}");
    }
}
