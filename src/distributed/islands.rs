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
use crate::islands::DisjointSets;
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
        let mut bodies = Vec::with_capacity(part.bodies.len());
        let (mut mass_at, mut first_at) = (0, 0);
        let (mut shared_first, mut own_first) = (0, 0);
        // Own bodies' first velocity there, by their index in the part.
        let mut own_place = vec![usize::MAX; part.bodies.len()];
        let mut own_m: Vec<(usize, usize, f64)> = Vec::new();
        let mut own_f = Vec::new();
        for (b, (&id, &k)) in part.bodies.iter().zip(&part.dofs).enumerate() {
            let block = &part.mass[mass_at..mass_at + k * k];
            let f = &part.f[first_at..first_at + k];
            if shared_body[b] {
                shared.bodies.push(id);
                shared.dofs.push(k);
                shared.mass.extend_from_slice(block);
                shared.f.extend_from_slice(f);
                bodies.push((Slot::Shared(shared_first), k));
                shared_first += k;
            } else {
                for (j, column) in block.chunks_exact(k).enumerate() {
                    for (i, &v) in column.iter().enumerate() {
                        if v != 0.0 {
                            own_m.push((own_first + i, own_first + j, v));
                        }
                    }
                }
                own_f.extend_from_slice(f);
                own_place[b] = own_first;
                bodies.push((Slot::Own(own_first), k));
                own_first += k;
            }
            mass_at += k * k;
            first_at += k;
        }
        let mut contacts = Vec::with_capacity(part.n_contacts());
        let (mut own_w, mut own_mu) = (Vec::new(), Vec::new());
        let (mut own_colptr, mut own_rows, mut own_values) = (vec![0], Vec::new(), Vec::new());
        for (c, &is_shared) in shared_contact.iter().enumerate() {
            let columns = 3 * c..3 * c + 3;
            if is_shared {
                contacts.push(Slot::Shared(shared.mu.len()));
                for j in columns {
                    let e = part.h_colptr[j]..part.h_colptr[j + 1];
                    shared.h_body.extend_from_slice(&part.h_body[e.clone()]);
                    shared.h_dof.extend_from_slice(&part.h_dof[e.clone()]);
                    shared.h_values.extend_from_slice(&part.h_values[e]);
                    shared.h_colptr.push(shared.h_body.len());
                }
                shared.w.extend_from_slice(&part.w[3 * c..3 * c + 3]);
                shared.mu.push(part.mu[c]);
            } else {
                contacts.push(Slot::Own(own_mu.len()));
                for j in columns {
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
                        own_rows.push(own_place[b] + dof);
                        own_values.push(part.h_values[e]);
                    }
                    own_colptr.push(own_rows.len());
                }
                own_w.extend_from_slice(&part.w[3 * c..3 * c + 3]);
                own_mu.push(part.mu[c]);
            }
        }
        let own = if own_first > 0 || !own_mu.is_empty() {
            let n = own_first;
            let problem = CscMatrix::from_triplets("M", n, n, &own_m)
                .and_then(|m| {
                    let columns = 3 * own_mu.len();
                    let h = CscMatrix::new("H", n, columns, own_colptr, own_rows, own_values)?;
                    GlobalProblem::new(m, h, own_f, own_w, own_mu)
                })
                .map_err(|e| (e.kind(), e.to_string()))?;
            Some(problem)
        } else {
            None
        };
        Ok(Self {
            shared,
            own,
            contacts,
            bodies,
        })
    }
}
