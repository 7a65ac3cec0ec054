//! Islands across processes (docs/algorithms.md §16): which of a process's contacts and
//! bodies are coupled, through contacts, to another process's, and which are not. The
//! ones that are not form islands inside the process, a one-process problem it solves
//! alone, as one process solves its islands; the others are the shared problem the
//! processes solve together.
//!
//! A process needs no global picture for this. Two processes' islands meet only at a body
//! one owns and the other's contacts touch, and the exchange plan of the whole part knows
//! those bodies on both sides. So each process joins, by union-find over its own
//! contacts, its bodies with one node standing for every body outside it, having joined
//! to that node the bodies other processes touch: what ends up with that node is shared.

use super::halo::{agree, agree_on, Halo};
use super::problem::{RankError, RankProblem};
use crate::csc::CscMatrix;
use crate::disjoint_sets::DisjointSets;
use crate::problem::GlobalProblem;
use crate::types::ErrorKind;
use mpi::topology::SimpleCommunicator;
use std::collections::HashMap;

/// Where one of a process's contacts or bodies went: into the shared problem or into the
/// process's own, at this contact or first velocity there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Slot {
    Shared(usize),
    Own(usize),
}

/// A process's part, cut into what it shares with the other processes and what it solves
/// alone.
pub(crate) struct RankSplit {
    /// The contacts and bodies coupled to another process's (global ids kept).
    pub shared: RankProblem,
    /// The process's own islands, renumbered (`None` when it has none).
    pub own: Option<GlobalProblem>,
    /// Where each of the part's contacts went.
    pub contacts: Vec<Slot>,
    /// Where each of the part's bodies went, with its velocities.
    pub bodies: Vec<(Slot, usize)>,
}

impl RankSplit {
    /// Cuts `part` (a collective call). With `islands` false, everything is shared: the
    /// problem is solved as one, as with one process's islands switched off.
    pub fn new(
        comm: &SimpleCommunicator,
        part: RankProblem,
        islands: bool,
    ) -> Result<Self, RankError> {
        if !islands {
            return Ok(Self::all_shared(part));
        }
        agree_on(comm, part.validate())?;
        let touched = part.h_body.iter().copied().enumerate();
        let halo = Halo::new(comm, &part.bodies, &part.dofs, touched)?;
        let nb = part.bodies.len();
        let outside = nb;
        let index: HashMap<u64, usize> = part
            .bodies
            .iter()
            .enumerate()
            .map(|(b, &id)| (id, b))
            .collect();
        let node = |id: &u64| index.get(id).copied().unwrap_or(outside);
        let mut sets = DisjointSets::new(nb + 1);
        // Owned bodies another process's contacts touch: their velocities are sent.
        let mut body_of = Vec::with_capacity(part.n_velocities());
        for (b, &k) in part.dofs.iter().enumerate() {
            body_of.extend(std::iter::repeat_n(b, k));
        }
        for &i in halo.shared_velocities() {
            sets.union(body_of[i], outside);
        }
        let entries = |c: usize| part.h_colptr[3 * c]..part.h_colptr[3 * c + 3];
        for c in 0..part.n_contacts() {
            let mut nodes = part.h_body[entries(c)].iter().map(node);
            if let Some(first) = nodes.next() {
                nodes.for_each(|n| sets.union(first, n));
            }
        }
        let root = sets.find(outside);
        let shared_body: Vec<bool> = (0..nb).map(|b| sets.find(b) == root).collect();
        // A contact with no entry touches nothing shared: it stays with the process.
        let shared_contact: Vec<bool> = (0..part.n_contacts())
            .map(|c| {
                let e = entries(c);
                e.start < e.end && sets.find(node(&part.h_body[e.start])) == root
            })
            .collect();
        let split = Self::cut(&part, &shared_body, &shared_contact, &index);
        agree(comm, split.as_ref().err().cloned())?;
        Ok(split.expect("agreed"))
    }

    /// Everything shared, nothing renumbered.
    fn all_shared(part: RankProblem) -> Self {
        let mut first = 0;
        let bodies = part
            .dofs
            .iter()
            .map(|&k| {
                first += k;
                (Slot::Shared(first - k), k)
            })
            .collect();
        Self {
            contacts: (0..part.n_contacts()).map(Slot::Shared).collect(),
            bodies,
            own: None,
            shared: part,
        }
    }

    /// The two problems, from which bodies and contacts are shared.
    fn cut(
        part: &RankProblem,
        shared_body: &[bool],
        shared_contact: &[bool],
        index: &HashMap<u64, usize>,
    ) -> Result<Self, (ErrorKind, String)> {
        let mut shared = RankProblem {
            h_colptr: vec![0],
            ..RankProblem::default()
        };
        let mut own = OwnIslands::new(part.bodies.len());
        let mut bodies = Vec::with_capacity(part.bodies.len());
        let (mut mass_at, mut first_at) = (0, 0);
        for (b, (&id, &k)) in part.bodies.iter().zip(&part.dofs).enumerate() {
            let block = &part.mass[mass_at..mass_at + k * k];
            let f = &part.f[first_at..first_at + k];
            let slot = if shared_body[b] {
                let first = shared.f.len();
                shared.bodies.push(id);
                shared.dofs.push(k);
                shared.mass.extend_from_slice(block);
                shared.f.extend_from_slice(f);
                Slot::Shared(first)
            } else {
                Slot::Own(own.add_body(b, block, f))
            };
            bodies.push((slot, k));
            mass_at += k * k;
            first_at += k;
        }
        let mut contacts = Vec::with_capacity(part.n_contacts());
        for (c, &is_shared) in shared_contact.iter().enumerate() {
            contacts.push(if is_shared {
                Slot::Shared(add_shared_contact(&mut shared, part, c))
            } else {
                Slot::Own(own.add_contact(part, c, index)?)
            });
        }
        Ok(Self {
            shared,
            own: own.problem()?,
            contacts,
            bodies,
        })
    }
}

/// Appends the part's contact `c` to the shared problem; its index there.
fn add_shared_contact(shared: &mut RankProblem, part: &RankProblem, c: usize) -> usize {
    for j in 3 * c..3 * c + 3 {
        let e = part.h_colptr[j]..part.h_colptr[j + 1];
        shared.h_body.extend_from_slice(&part.h_body[e.clone()]);
        shared.h_dof.extend_from_slice(&part.h_dof[e.clone()]);
        shared.h_values.extend_from_slice(&part.h_values[e]);
        shared.h_colptr.push(shared.h_body.len());
    }
    shared.w.extend_from_slice(&part.w[3 * c..3 * c + 3]);
    shared.mu.push(part.mu[c]);
    shared.mu.len() - 1
}

/// A process's own islands as the cut gathers them, renumbered: `M` as triplets, `f`, and
/// the columns of `H` with `w` and `mu`, contact by contact.
struct OwnIslands {
    /// Velocities so far.
    n: usize,
    /// Own bodies' first velocity here, by their index in the part.
    place: Vec<usize>,
    m: Vec<(usize, usize, f64)>,
    f: Vec<f64>,
    colptr: Vec<usize>,
    rows: Vec<usize>,
    values: Vec<f64>,
    w: Vec<f64>,
    mu: Vec<f64>,
}

impl OwnIslands {
    /// Nothing yet, for a part of `n_bodies` bodies.
    fn new(n_bodies: usize) -> Self {
        Self {
            n: 0,
            place: vec![usize::MAX; n_bodies],
            m: Vec::new(),
            f: Vec::new(),
            colptr: vec![0],
            rows: Vec::new(),
            values: Vec::new(),
            w: Vec::new(),
            mu: Vec::new(),
        }
    }

    /// Appends the part's body `b`, of mass block `block` (column-major) and force `f`;
    /// its first velocity here.
    fn add_body(&mut self, b: usize, block: &[f64], f: &[f64]) -> usize {
        let (first, k) = (self.n, f.len());
        for (j, column) in block.chunks_exact(k).enumerate() {
            for (i, &v) in column.iter().enumerate() {
                if v != 0.0 {
                    self.m.push((first + i, first + j, v));
                }
            }
        }
        self.f.extend_from_slice(f);
        self.place[b] = first;
        self.n += k;
        first
    }

    /// Appends the part's contact `c`, whose bodies are all own bodies (`index` gives a
    /// body id's index in the part); its index here.
    fn add_contact(
        &mut self,
        part: &RankProblem,
        c: usize,
        index: &HashMap<u64, usize>,
    ) -> Result<usize, (ErrorKind, String)> {
        for j in 3 * c..3 * c + 3 {
            for e in part.h_colptr[j]..part.h_colptr[j + 1] {
                // Every body of an own contact is an own body of this process.
                let (id, dof) = (part.h_body[e], part.h_dof[e]);
                let b = index[&id];
                if dof >= part.dofs[b] {
                    return Err((
                        ErrorKind::InvalidValue,
                        format!(
                            "h_dof[{e}]: velocity {dof} of body id {id}, which has {}",
                            part.dofs[b]
                        ),
                    ));
                }
                self.rows.push(self.place[b] + dof);
                self.values.push(part.h_values[e]);
            }
            self.colptr.push(self.rows.len());
        }
        self.w.extend_from_slice(&part.w[3 * c..3 * c + 3]);
        self.mu.push(part.mu[c]);
        Ok(self.mu.len() - 1)
    }

    /// The islands' problem (`None` when there are none).
    fn problem(self) -> Result<Option<GlobalProblem>, (ErrorKind, String)> {
        if self.n == 0 && self.mu.is_empty() {
            return Ok(None);
        }
        let n = self.n;
        let problem = CscMatrix::from_triplets("M", n, n, &self.m)
            .and_then(|m| {
                let columns = 3 * self.mu.len();
                let h = CscMatrix::new("H", n, columns, self.colptr, self.rows, self.values)?;
                GlobalProblem::new(m, h, self.f, self.w, self.mu)
            })
            .map_err(|e| (e.kind(), e.to_string()))?;
        Ok(Some(problem))
    }
}
