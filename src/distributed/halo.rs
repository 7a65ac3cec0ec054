//! Who holds which velocities. A process's vectors over the velocities hold its own
//! bodies' velocities first, then copies of the velocities of the other processes' bodies
//! that its contacts touch, grouped by owner in rank order and by id within an owner.
//! [`Halo::share`] brings the copies up to date from their owners; [`Halo::gather_back`]
//! adds what a process accumulated in its copies into the owners' entries, each owner
//! adding the contributions in rank order. [`Halo::sum_across`] adds up partial sums,
//! also in rank order: the results depend on the number of processes, not on timing.

use super::problem::RankError;
use crate::types::{Error, ErrorKind};
use mpi::datatype::{Partition, PartitionMut};
use mpi::topology::{Communicator, SimpleCommunicator};
use mpi::traits::*;
use mpi::Count;
use std::cell::{Cell, RefCell};
use std::collections::HashMap;
use std::time::Instant;

/// Where a body's velocities are in this process's vectors.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Place {
    /// First velocity.
    pub first: usize,
    /// Number of velocities.
    pub dofs: usize,
}

/// The exchange plan between the processes sharing a problem.
pub(crate) struct Halo {
    comm: SimpleCommunicator,
    /// Velocities this process owns (the first entries of its vectors).
    owned: usize,
    /// Owned velocities each process holds copies of: `send[send_displs[r]..]`, in the
    /// order of that process's copies.
    send: Vec<usize>,
    send_counts: Vec<Count>,
    send_displs: Vec<Count>,
    /// Copies received from each process (after the owned velocities, in rank order).
    recv_counts: Vec<Count>,
    recv_displs: Vec<Count>,
    /// Where each body this process touches (owned or copied) sits, by global id.
    places: HashMap<u64, Place>,
    /// The bodies' places in the order of this process's vectors.
    layout: Vec<Place>,
    out: Vec<f64>,
    back: Vec<f64>,
    /// Every process's partial sums, for [`Halo::sum_across`].
    gathered: RefCell<Vec<f64>>,
    /// Seconds spent in the exchanges (waiting for the other processes included).
    exchanging: Cell<f64>,
}

impl Halo {
    /// The plan for a process that owns `bodies` (global ids, with their `dofs`) and
    /// whose contacts touch the bodies `touched` (global ids, any order, repeats
    /// allowed). Every process gets the same error when a body is owned twice or a touched
    /// body by no process.
    pub fn new(
        comm: &SimpleCommunicator,
        bodies: &[u64],
        dofs: &[usize],
        touched: impl Iterator<Item = (usize, u64)>,
    ) -> Result<Self, RankError> {
        let comm = comm.duplicate();
        let size = comm.size() as usize;
        let owner = owners(&comm, bodies, dofs)?;
        let owned: usize = dofs.iter().sum();
        let copied = copied_bodies(&comm, &owner, touched)?;
        let mut places: HashMap<u64, Place> = HashMap::new();
        let mut layout = Vec::with_capacity(bodies.len() + copied.len());
        let mut first = 0;
        for (&id, &d) in bodies.iter().zip(dofs) {
            let place = Place { first, dofs: d };
            places.insert(id, place);
            layout.push(place);
            first += d;
        }
        // Ask each owner for its bodies' velocities, as indices into the owner's vectors.
        let mut wanted = vec![Vec::new(); size];
        for &(r, id) in &copied {
            let place = owner[&id].1;
            let copy = Place {
                first,
                dofs: place.dofs,
            };
            places.insert(id, copy);
            layout.push(copy);
            first += place.dofs;
            wanted[r].extend((place.first..place.first + place.dofs).map(|i| i as u64));
        }
        let recv_counts: Vec<Count> = wanted.iter().map(|w| w.len() as Count).collect();
        let recv_displs = displacements(&recv_counts);
        let requests: Vec<u64> = wanted.concat();
        let mut send_counts = vec![0 as Count; size];
        comm.all_to_all_into(&recv_counts[..], &mut send_counts[..]);
        let send_displs = displacements(&send_counts);
        let mut send = vec![0u64; send_counts.iter().sum::<Count>() as usize];
        comm.all_to_all_varcount_into(
            &Partition::new(&requests[..], &recv_counts[..], &recv_displs[..]),
            &mut PartitionMut::new(&mut send[..], &send_counts[..], &send_displs[..]),
        );
        Ok(Self {
            out: vec![0.0; send.len()],
            back: vec![0.0; requests.len()],
            send: send.into_iter().map(|i| i as usize).collect(),
            comm,
            owned,
            send_counts,
            send_displs,
            recv_counts,
            recv_displs,
            places,
            layout,
            gathered: RefCell::new(Vec::new()),
            exchanging: Cell::new(0.0),
        })
    }

    /// Velocities this process owns.
    pub fn owned(&self) -> usize {
        self.owned
    }

    /// Owned velocities other processes hold copies of (each once per process holding it).
    pub fn shared_velocities(&self) -> &[usize] {
        &self.send
    }

    /// Length of this process's vectors: owned velocities, then copies.
    pub fn local(&self) -> usize {
        self.owned + self.back.len()
    }

    /// Where the body `id` sits in this process's vectors (it owns or copies it).
    pub fn place(&self, id: u64) -> Place {
        self.places[&id]
    }

    /// The bodies' places, in the order of this process's vectors.
    pub fn layout(&self) -> &[Place] {
        &self.layout
    }

    /// The communicator of the processes sharing the problem.
    pub fn comm(&self) -> &SimpleCommunicator {
        &self.comm
    }

    /// Writes the owners' values into the copies of `x` (of length [`Halo::local`]).
    pub fn share(&mut self, x: &mut [f64]) {
        for (o, &i) in self.out.iter_mut().zip(&self.send) {
            *o = x[i];
        }
        let t0 = Instant::now();
        self.comm.all_to_all_varcount_into(
            &Partition::new(&self.out[..], &self.send_counts[..], &self.send_displs[..]),
            &mut PartitionMut::new(
                &mut x[self.owned..],
                &self.recv_counts[..],
                &self.recv_displs[..],
            ),
        );
        self.count(t0);
    }

    /// Adds the copies of `y` into their owners' entries (each owner in rank order of the
    /// processes that hold copies) and zeroes the copies.
    pub fn gather_back(&mut self, y: &mut [f64]) {
        let copies = &mut y[self.owned..];
        self.back.copy_from_slice(copies);
        copies.fill(0.0);
        let t0 = Instant::now();
        self.comm.all_to_all_varcount_into(
            &Partition::new(&self.back[..], &self.recv_counts[..], &self.recv_displs[..]),
            &mut PartitionMut::new(
                &mut self.out[..],
                &self.send_counts[..],
                &self.send_displs[..],
            ),
        );
        self.count(t0);
        for (&i, o) in self.send.iter().zip(&self.out) {
            y[i] += o;
        }
    }

    /// [`Halo::gather_back`] for vectors with `width` entries per velocity (velocity `i`'s
    /// are `width i..width (i + 1)`); rare (the preconditioner's blocks), so it allocates.
    pub fn gather_back_wide(&self, y: &mut [f64], width: usize) {
        let scale = |c: &[Count]| -> Vec<Count> { c.iter().map(|n| n * width as Count).collect() };
        let (recv_counts, recv_displs) = (scale(&self.recv_counts), scale(&self.recv_displs));
        let (send_counts, send_displs) = (scale(&self.send_counts), scale(&self.send_displs));
        let copies = &mut y[width * self.owned..];
        let back = copies.to_vec();
        copies.fill(0.0);
        let mut out = vec![0.0; width * self.send.len()];
        self.comm.all_to_all_varcount_into(
            &Partition::new(&back[..], &recv_counts[..], &recv_displs[..]),
            &mut PartitionMut::new(&mut out[..], &send_counts[..], &send_displs[..]),
        );
        for (&i, o) in self.send.iter().zip(out.chunks_exact(width)) {
            for (a, b) in y[width * i..width * (i + 1)].iter_mut().zip(o) {
                *a += b;
            }
        }
    }

    /// Seconds spent in the exchanges since the plan was made (waiting for the other
    /// processes included): what the scaling benchmark reports as communication.
    pub fn exchange_seconds(&self) -> f64 {
        self.exchanging.get()
    }

    fn count(&self, since: Instant) {
        self.exchanging
            .set(self.exchanging.get() + since.elapsed().as_secs_f64());
    }

    /// The largest of every process's `x` (exact, whatever the order).
    pub fn max_across(&self, x: f64) -> f64 {
        let mut max = x;
        self.comm
            .all_reduce_into(&x, &mut max, mpi::collective::SystemOperation::max());
        max
    }

    /// The largest of every process's entries, entry by entry (exact, whatever the order).
    pub fn max_across_each(&self, x: &mut [f64]) {
        let mine = x.to_vec();
        self.comm
            .all_reduce_into(&mine[..], x, mpi::collective::SystemOperation::max());
    }

    /// Adds up, entry by entry, every process's `partial`, in rank order (a gather, then
    /// the same sum on every process: no reduction tree whose order could vary). The
    /// gather buffer grows to the longest sum asked for, then is reused.
    pub fn sum_across(&self, partial: &mut [f64]) {
        let size = self.comm.size() as usize;
        if size == 1 || partial.is_empty() {
            return;
        }
        let mut all = self.gathered.borrow_mut();
        if all.len() < size * partial.len() {
            all.resize(size * partial.len(), 0.0);
        }
        let all = &mut all[..size * partial.len()];
        let t0 = Instant::now();
        self.comm.all_gather_into(&*partial, all);
        self.count(t0);
        partial.fill(0.0);
        for part in all.chunks_exact(partial.len()) {
            for (p, v) in partial.iter_mut().zip(part) {
                *p += v;
            }
        }
    }
}

/// Every process learns whether one failed: the lowest failing rank's error (its kind and
/// message) becomes every process's.
pub(crate) fn agree(
    comm: &SimpleCommunicator,
    failure: Option<(ErrorKind, String)>,
) -> Result<(), RankError> {
    let index = |kind| ErrorKind::ALL.iter().position(|&k| k == kind).unwrap_or(0) as u8;
    agree_code(comm, failure.map(|(kind, message)| (index(kind), message))).map_err(
        |(rank, code, message)| RankError {
            rank,
            kind: ErrorKind::ALL[usize::from(code).min(ErrorKind::ALL.len() - 1)],
            message,
        },
    )
}

/// [`agree`] with the error as a code of the caller's (the C API's result codes): the
/// lowest failing rank, its code and its message, on every process.
pub(crate) fn agree_code(
    comm: &SimpleCommunicator,
    failure: Option<(u8, String)>,
) -> Result<(), (usize, u8, String)> {
    let mut failed = vec![0u8; comm.size() as usize];
    comm.all_gather_into(&u8::from(failure.is_some()), &mut failed[..]);
    let Some(rank) = failed.iter().position(|&f| f != 0) else {
        return Ok(());
    };
    let root = comm.process_at_rank(rank as i32);
    let (mut code, message) = failure.unwrap_or_default();
    let mut bytes = message.into_bytes();
    let mut len = bytes.len() as u64;
    root.broadcast_into(&mut code);
    root.broadcast_into(&mut len);
    bytes.resize(len as usize, 0);
    root.broadcast_into(&mut bytes[..]);
    Err((rank, code, String::from_utf8_lossy(&bytes).into_owned()))
}

/// [`agree`] on this process's outcome.
pub(crate) fn agree_on(
    comm: &SimpleCommunicator,
    outcome: Result<(), Error>,
) -> Result<(), RankError> {
    agree(comm, outcome.err().map(|e| (e.kind(), e.to_string())))
}

/// Every process's `mine`, rank after rank.
pub(crate) fn all_gather_varcount(comm: &SimpleCommunicator, mine: &[u64]) -> Vec<Vec<u64>> {
    let mut counts = vec![0 as Count; comm.size() as usize];
    comm.all_gather_into(&(mine.len() as Count), &mut counts[..]);
    let displs = displacements(&counts);
    let mut all = vec![0u64; counts.iter().sum::<Count>() as usize];
    comm.all_gather_varcount_into(
        mine,
        &mut PartitionMut::new(&mut all[..], &counts[..], &displs[..]),
    );
    counts
        .iter()
        .zip(&displs)
        .map(|(&n, &d)| all[d as usize..(d + n) as usize].to_vec())
        .collect()
}

/// Every body's owner and place there, learnt from every process (a collective call); the
/// same error on every process when a body is owned twice.
fn owners(
    comm: &SimpleCommunicator,
    bodies: &[u64],
    dofs: &[usize],
) -> Result<HashMap<u64, (usize, Place)>, RankError> {
    let ids = all_gather_varcount(comm, bodies);
    let dofs_all = all_gather_varcount(comm, &dofs.iter().map(|&k| k as u64).collect::<Vec<_>>());
    let mut owner: HashMap<u64, (usize, Place)> = HashMap::with_capacity(ids.len());
    for (r, (ids, dofs)) in ids.iter().zip(&dofs_all).enumerate() {
        let mut first = 0;
        for (k, (&id, &d)) in ids.iter().zip(dofs).enumerate() {
            let place = Place {
                first,
                dofs: d as usize,
            };
            if let Some((other, _)) = owner.insert(id, (r, place)) {
                return Err(RankError {
                    rank: r,
                    kind: ErrorKind::InvalidValue,
                    message: format!("bodies[{k}]: body id {id} is owned by rank {other} too"),
                });
            }
            first += d as usize;
        }
    }
    Ok(owner)
}

/// The other processes' bodies among `touched` (entry, id), as (owner, id) by owner then
/// id, each once (a collective call); the same error on every process when a process
/// touches a body no process owns.
fn copied_bodies(
    comm: &SimpleCommunicator,
    owner: &HashMap<u64, (usize, Place)>,
    touched: impl Iterator<Item = (usize, u64)>,
) -> Result<Vec<(usize, u64)>, RankError> {
    let rank = comm.rank() as usize;
    let mut copied: Vec<(usize, u64)> = Vec::new();
    let mut unknown = None;
    for (entry, id) in touched {
        match owner.get(&id) {
            Some(&(r, _)) if r != rank => copied.push((r, id)),
            Some(_) => {}
            None => {
                unknown.get_or_insert((entry, id));
            }
        }
    }
    agree(
        comm,
        unknown.map(|(entry, id)| {
            (
                ErrorKind::InvalidValue,
                format!("h_body[{entry}]: body id {id} is owned by no process"),
            )
        }),
    )?;
    copied.sort_unstable();
    copied.dedup();
    Ok(copied)
}

/// Offsets of consecutive runs of `counts` entries.
fn displacements(counts: &[Count]) -> Vec<Count> {
    counts
        .iter()
        .scan(0, |at, &n| {
            let d = *at;
            *at += n;
            Some(d)
        })
        .collect()
}
