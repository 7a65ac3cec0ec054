//! Contact islands (docs/algorithms.md §12): the connected components of a problem's
//! coupling graph, and the sub-problem of each.
//!
//! Global form: M's off-diagonal entries couple velocities, a contact (its three columns of
//! H) couples the velocities it touches, and so does a joint (its column of G). Local form:
//! W's 3x3 blocks couple contacts. The sparsity pattern decides, not the values (a stored
//! zero couples), so a partition holds for every update on the same pattern.

use crate::csc::CscMatrix;
// The partition of a distributed problem finds its components with them too.
use crate::disjoint_sets::DisjointSets;
use crate::problem::{GlobalProblem, LocalProblem, NewValues, Problem};
use crate::types::Error;

/// One part of a problem: the indices it holds in the whole problem, increasing, and where
/// each stored matrix entry of its sub-problem comes from in the whole problem's storage.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Part {
    /// Velocities (global form).
    pub velocities: Vec<usize>,
    /// Contacts.
    pub contacts: Vec<usize>,
    /// Joint columns (global form).
    pub joints: Vec<usize>,
    /// Stored entries of M (global form) or W (local form), in the sub-problem's order.
    pub m_entries: Vec<usize>,
    /// Stored entries of H.
    pub h_entries: Vec<usize>,
    /// Stored entries of G.
    pub g_entries: Vec<usize>,
}

/// How a problem splits.
#[derive(Debug, Default)]
pub(crate) struct Partition {
    /// The contact islands, ordered by their first contact.
    pub islands: Vec<Part>,
    /// Global form: the velocities no contact reaches, with their joints; solved as one
    /// contact-free problem (`v = M^-1 f`, or the joint system).
    pub free: Option<Part>,
    /// Global form: contacts whose columns of H are empty, which no velocity moves: their
    /// relative velocity is `w` whatever the impulse, so `r = 0` is their only candidate.
    pub bodiless: Vec<usize>,
}

impl Partition {
    /// True when the problem is one coupled part (nothing to split).
    pub fn is_whole(&self) -> bool {
        self.bodiless.is_empty() && self.islands.len() + usize::from(self.free.is_some()) <= 1
    }
}

/// Rows of column `j` of `a`.
fn rows(a: &CscMatrix, j: usize) -> &[usize] {
    &a.rowind()[a.colptr()[j]..a.colptr()[j + 1]]
}

/// Partition of a global problem.
pub(crate) fn partition_global(p: &GlobalProblem) -> Partition {
    let (n, nc) = (p.n(), p.n_contacts());
    // Nodes: the velocities, then one per contact.
    let mut sets = DisjointSets::new(n + nc);
    for j in 0..n {
        for &i in rows(&p.m, j) {
            sets.union(i, j);
        }
    }
    let bounds_a_row = couple_rows_to_contacts(p, &mut sets);
    let mut bodiless = Vec::new();
    for c in 0..nc {
        let mut touched = bounds_a_row[c];
        for k in 3 * c..3 * c + 3 {
            for &i in rows(&p.h, k) {
                sets.union(n + c, i);
                touched = true;
            }
        }
        if !touched {
            bodiless.push(c);
        }
    }
    if let Some(j) = &p.joints {
        for k in 0..j.g.ncols() {
            let r = rows(&j.g, k);
            for &i in r.iter().skip(1) {
                sets.union(r[0], i);
            }
        }
    }
    // Island of each root, numbered in the order of first contacts.
    let mut island_of_root = vec![usize::MAX; n + nc];
    let mut islands: Vec<Part> = Vec::new();
    for c in 0..nc {
        if bodiless.binary_search(&c).is_ok() {
            continue;
        }
        let root = sets.find(n + c);
        if island_of_root[root] == usize::MAX {
            island_of_root[root] = islands.len();
            islands.push(Part::default());
        }
        islands[island_of_root[root]].contacts.push(c);
    }
    let mut free = Part::default();
    for i in 0..n {
        match island_of_root[sets.find(i)] {
            usize::MAX => free.velocities.push(i),
            k => islands[k].velocities.push(i),
        }
    }
    if let Some(j) = &p.joints {
        for k in 0..j.g.ncols() {
            // A joint column without entries constrains no velocity: it goes with the
            // contact-free part, where the measure judges its `b`.
            let island = rows(&j.g, k)
                .first()
                .map_or(usize::MAX, |&i| island_of_root[sets.find(i)]);
            match island {
                usize::MAX => free.joints.push(k),
                k_island => islands[k_island].joints.push(k),
            }
        }
    }
    let free = (!free.velocities.is_empty() || !free.joints.is_empty()).then_some(free);
    Partition {
        islands,
        free,
        bodiless,
    }
}

/// Couples each joint row bounded by a contact (rolling or spinning friction) to that
/// contact's node in `sets` (the velocities, then one node per contact); returns which
/// contacts bound a row.
fn couple_rows_to_contacts(p: &GlobalProblem, sets: &mut DisjointSets) -> Vec<bool> {
    let mut bounds_a_row = vec![false; p.n_contacts()];
    if let Some(j) = &p.joints {
        for (k, c) in j.friction_contact.iter().enumerate() {
            if let (Some(c), Some(&i)) = (c, rows(&j.g, k).first()) {
                sets.union(p.n() + c, i);
                bounds_a_row[*c] = true;
            }
        }
    }
    bounds_a_row
}

/// Partition of a local problem.
pub(crate) fn partition_local(p: &LocalProblem) -> Partition {
    let nc = p.n_contacts();
    let mut sets = DisjointSets::new(nc);
    for j in 0..3 * nc {
        for &i in rows(&p.w, j) {
            sets.union(i / 3, j / 3);
        }
    }
    let mut island_of_root = vec![usize::MAX; nc];
    let mut islands: Vec<Part> = Vec::new();
    for c in 0..nc {
        let root = sets.find(c);
        if island_of_root[root] == usize::MAX {
            island_of_root[root] = islands.len();
            islands.push(Part::default());
        }
        islands[island_of_root[root]].contacts.push(c);
    }
    Partition {
        islands,
        ..Partition::default()
    }
}

/// Where each velocity (global form) or contact row (local form) sits in its part: one map
/// for all parts, since every index belongs to one part at most (built once, so that
/// splitting costs the size of the problem, not that times the number of islands).
pub(crate) fn positions(parts: &[&Part], len: usize, global: bool) -> Vec<usize> {
    let mut at = vec![usize::MAX; len];
    for part in parts {
        if global {
            for (k, &i) in part.velocities.iter().enumerate() {
                at[i] = k;
            }
        } else {
            for (k, i) in contact_rows(&part.contacts).enumerate() {
                at[i] = k;
            }
        }
    }
    at
}

/// The columns `cols` of `a`, rows renumbered by `row_of` (every row of those columns is in
/// the part), with the whole matrix's stored entry of each new entry. Rows stay sorted
/// because the renumbering keeps their order.
fn sub_matrix(
    field: &'static str,
    a: &CscMatrix,
    nrows: usize,
    cols: impl Iterator<Item = usize> + Clone,
    row_of: &[usize],
) -> Result<(CscMatrix, Vec<usize>), Error> {
    // Sized exactly first: a scene of many islands builds many of these.
    let ncols = cols.clone().count();
    let nnz = cols
        .clone()
        .map(|j| a.colptr()[j + 1] - a.colptr()[j])
        .sum();
    let mut colptr = Vec::with_capacity(ncols + 1);
    colptr.push(0);
    let (mut rowind, mut values, mut entries) = (
        Vec::with_capacity(nnz),
        Vec::with_capacity(nnz),
        Vec::with_capacity(nnz),
    );
    for j in cols {
        for k in a.colptr()[j]..a.colptr()[j + 1] {
            rowind.push(row_of[a.rowind()[k]]);
            values.push(a.values()[k]);
            entries.push(k);
        }
        colptr.push(rowind.len());
    }
    Ok((
        CscMatrix::new(field, nrows, ncols, colptr, rowind, values)?,
        entries,
    ))
}

/// The entries `3 c`, `3 c + 1`, `3 c + 2` of each contact `c`.
pub(crate) fn contact_rows(contacts: &[usize]) -> impl Iterator<Item = usize> + Clone + '_ {
    contacts.iter().flat_map(|&c| 3 * c..3 * c + 3)
}

/// `x[indices]`, new.
fn pick(x: &[f64], indices: impl Iterator<Item = usize>) -> Vec<f64> {
    indices.map(|i| x[i]).collect()
}

/// `x[indices]` into `out`.
pub(crate) fn gather(x: &[f64], indices: impl Iterator<Item = usize>, out: &mut [f64]) {
    for (o, i) in out.iter_mut().zip(indices) {
        *o = x[i];
    }
}

impl Part {
    /// The sub-problem of a global problem on this part; fills the entry maps. `row_of`:
    /// [`positions`] of the velocities.
    pub fn global_problem(
        &mut self,
        p: &GlobalProblem,
        row_of: &[usize],
    ) -> Result<GlobalProblem, Error> {
        let nv = self.velocities.len();
        let (m, m_entries) = sub_matrix("M", &p.m, nv, self.velocities.iter().copied(), row_of)?;
        let (h, h_entries) = sub_matrix("H", &p.h, nv, contact_rows(&self.contacts), row_of)?;
        let f = pick(&p.f, self.velocities.iter().copied());
        let w = pick(&p.w, contact_rows(&self.contacts));
        let mu = pick(&p.mu, self.contacts.iter().copied());
        let mut sub = GlobalProblem::new(m, h, f, w, mu)?;
        self.m_entries = m_entries;
        self.h_entries = h_entries;
        if let Some(j) = &p.joints {
            let (g, g_entries) = sub_matrix("G", &j.g, nv, self.joints.iter().copied(), row_of)?;
            let rows = || self.joints.iter().copied();
            // A row bounded by a contact names it in the part's numbering (the partition
            // put both in one part).
            let contact = |c: Option<usize>| c.and_then(|c| self.contacts.binary_search(&c).ok());
            sub = sub
                .with_joints(g, pick(&j.b, rows()))?
                .with_joint_bounds(pick(&j.lo, rows()), pick(&j.hi, rows()))?
                .with_joint_compliance(pick(&j.compliance, rows()))?
                .with_joint_friction(
                    rows().map(|k| contact(j.friction_contact[k])).collect(),
                    pick(&j.friction, rows()),
                )?;
            self.g_entries = g_entries;
        }
        Ok(sub)
    }

    /// The sub-problem of either form on this part; fills the entry maps.
    pub fn sub_problem(&mut self, whole: &Problem, row_of: &[usize]) -> Result<Problem, Error> {
        Ok(match whole {
            Problem::Global(g) => Problem::Global(self.global_problem(g, row_of)?),
            Problem::Local(l) => Problem::Local(self.local_problem(l, row_of)?),
        })
    }

    /// The sub-problem of a local problem on this part; fills the entry map. `row_of`:
    /// [`positions`] of the contact rows.
    pub fn local_problem(
        &mut self,
        p: &LocalProblem,
        row_of: &[usize],
    ) -> Result<LocalProblem, Error> {
        let m = 3 * self.contacts.len();
        let (w, entries) = sub_matrix("W", &p.w, m, contact_rows(&self.contacts), row_of)?;
        let q = pick(&p.q, contact_rows(&self.contacts));
        let mu = pick(&p.mu, self.contacts.iter().copied());
        self.m_entries = entries;
        LocalProblem::new(w, q, mu)
    }
}

/// Buffers that carry a part's share of new values: empty by default, each sized by the
/// first update that needs it and reused by the next ones.
#[derive(Debug, Default)]
pub(crate) struct ValueBuffers {
    m: Vec<f64>,
    h: Vec<f64>,
    g: Vec<f64>,
    f: Vec<f64>,
    w: Vec<f64>,
    /// The joint rows' `b`, `lo`, `hi`, compliance and friction coefficients.
    rows: [Vec<f64>; 5],
    mu: Vec<f64>,
}

impl ValueBuffers {
    /// The part's share of the global problem `p`'s values, for the fields `given` names
    /// (the others stay `None`, as in the caller's update).
    pub fn global<'a>(
        &'a mut self,
        part: &Part,
        p: &GlobalProblem,
        given: &NewValues,
    ) -> NewValues<'a> {
        // A part without joint rows (an island of contacts alone in a scene with joints)
        // has a problem without joints, which takes no joint values.
        let joints = p.joints.as_ref().filter(|_| !part.joints.is_empty());
        let mut out = NewValues::default();
        if given.m.is_some() {
            out.m = Some(gather_sized(
                p.m.values(),
                part.m_entries.iter().copied(),
                &mut self.m,
            ));
        }
        if given.h.is_some() {
            out.h = Some(gather_sized(
                p.h.values(),
                part.h_entries.iter().copied(),
                &mut self.h,
            ));
        }
        if let (Some(j), true) = (joints, given.g.is_some()) {
            out.g = Some(gather_sized(
                j.g.values(),
                part.g_entries.iter().copied(),
                &mut self.g,
            ));
        }
        if let Some(j) = joints {
            let rows = part.joints.iter().copied();
            let [b, lo, hi, compliance, friction] = &mut self.rows;
            let pick = |given: Option<&[f64]>, x: &[f64], buf: &'a mut Vec<f64>| {
                given.map(|_| gather_sized(x, rows.clone(), buf))
            };
            out.b = pick(given.b, &j.b, b);
            out.lo = pick(given.lo, &j.lo, lo);
            out.hi = pick(given.hi, &j.hi, hi);
            out.compliance = pick(given.compliance, &j.compliance, compliance);
            out.friction = pick(given.friction, &j.friction, friction);
        }
        if given.f.is_some() {
            out.f = Some(gather_sized(
                &p.f,
                part.velocities.iter().copied(),
                &mut self.f,
            ));
        }
        if given.w.is_some() {
            out.w = Some(gather_sized(
                &p.w,
                contact_rows(&part.contacts),
                &mut self.w,
            ));
        }
        if given.mu.is_some() {
            out.mu = Some(gather_sized(
                &p.mu,
                part.contacts.iter().copied(),
                &mut self.mu,
            ));
        }
        out
    }

    /// The part's share of the local problem `p`'s values, for the fields `given` names.
    pub fn local<'a>(
        &'a mut self,
        part: &Part,
        p: &LocalProblem,
        given: &NewValues,
    ) -> NewValues<'a> {
        let mut out = NewValues::default();
        if given.delassus.is_some() {
            out.delassus = Some(gather_sized(
                p.w.values(),
                part.m_entries.iter().copied(),
                &mut self.m,
            ));
        }
        if given.q.is_some() {
            out.q = Some(gather_sized(
                &p.q,
                contact_rows(&part.contacts),
                &mut self.w,
            ));
        }
        if given.mu.is_some() {
            out.mu = Some(gather_sized(
                &p.mu,
                part.contacts.iter().copied(),
                &mut self.mu,
            ));
        }
        out
    }
}

/// `x[indices]` into `out`, resized to the number of indices (allocates only when it
/// grows); returns `out`.
fn gather_sized<'a>(
    x: &[f64],
    indices: impl Iterator<Item = usize> + Clone,
    out: &'a mut Vec<f64>,
) -> &'a [f64] {
    out.resize(indices.clone().count(), 0.0);
    gather(x, indices, out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two bodies (3 velocities each) with a contact each, a third body with no contact,
    /// and a contact that touches nothing.
    fn scene() -> GlobalProblem {
        let m = CscMatrix::identity(9);
        let h = CscMatrix::from_triplets(
            "H",
            9,
            9,
            &[
                (0, 0, 1.0),
                (1, 1, 1.0),
                (2, 2, 1.0),
                (3, 3, 1.0),
                (4, 4, 1.0),
            ],
        )
        .unwrap();
        GlobalProblem::new(m, h, vec![-1.0; 9], vec![0.0; 9], vec![0.5; 3]).unwrap()
    }

    #[test]
    fn global_partition_finds_islands_free_bodies_and_bodiless_contacts() {
        let p = scene();
        let part = partition_global(&p);
        // Contact 0 touches velocities 0, 1, 2; contact 1 touches 3, 4; contact 2 nothing.
        assert_eq!(part.islands.len(), 2);
        assert_eq!(part.islands[0].contacts, vec![0]);
        assert_eq!(part.islands[0].velocities, vec![0, 1, 2]);
        assert_eq!(part.islands[1].contacts, vec![1]);
        assert_eq!(part.islands[1].velocities, vec![3, 4]);
        assert_eq!(part.free.as_ref().unwrap().velocities, vec![5, 6, 7, 8]);
        assert_eq!(part.bodiless, vec![2]);
        assert!(!part.is_whole());
    }

    #[test]
    fn an_off_diagonal_mass_entry_joins_islands() {
        let mut p = scene();
        p.m = CscMatrix::from_triplets(
            "M",
            9,
            9,
            &(0..9)
                .map(|i| (i, i, 2.0))
                .chain([(2, 3, 0.5), (3, 2, 0.5)])
                .collect::<Vec<_>>(),
        )
        .unwrap();
        let part = partition_global(&p);
        assert_eq!(part.islands.len(), 1);
        assert_eq!(part.islands[0].contacts, vec![0, 1]);
        assert_eq!(part.islands[0].velocities, vec![0, 1, 2, 3, 4]);
    }

    #[test]
    fn a_sub_problem_holds_its_entries_and_their_origin() {
        let p = scene();
        let mut part = partition_global(&p);
        let at = positions(&[&part.islands[1]], p.n(), true);
        let sub = part.islands[1].global_problem(&p, &at).unwrap();
        assert_eq!(sub.n(), 2);
        assert_eq!(sub.n_contacts(), 1);
        // H column 3 (contact 1's normal) has its entry at velocity 3, now velocity 0.
        assert_eq!(sub.h.col(0).collect::<Vec<_>>(), vec![(0, 1.0)]);
        for (s, &k) in part.islands[1].h_entries.iter().enumerate() {
            assert_eq!(sub.h.values()[s], p.h.values()[k]);
        }
    }

    #[test]
    fn local_partition_follows_the_blocks_of_w() {
        // Contacts 0 and 2 coupled, contact 1 alone.
        let mut t: Vec<(usize, usize, f64)> = (0..9).map(|i| (i, i, 1.0)).collect();
        t.extend([(0, 6, 0.1), (6, 0, 0.1)]);
        let w = CscMatrix::from_triplets("W", 9, 9, &t).unwrap();
        let p = LocalProblem::new(w, vec![-1.0; 9], vec![0.3; 3]).unwrap();
        let mut part = partition_local(&p);
        assert_eq!(part.islands.len(), 2);
        assert_eq!(part.islands[0].contacts, vec![0, 2]);
        assert_eq!(part.islands[1].contacts, vec![1]);
        let at = positions(&[&part.islands[0]], p.q.len(), false);
        let sub = part.islands[0].local_problem(&p, &at).unwrap();
        assert_eq!(sub.w.nrows(), 6);
        assert_eq!(sub.w.col(0).collect::<Vec<_>>(), vec![(0, 1.0), (3, 0.1)]);
    }
}
