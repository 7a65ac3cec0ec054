//! One problem solved across MPI processes (feature `mpi`): piles split into slabs by
//! position, as a host engine would split them, solved on 1, 2 and 4 processes and
//! compared with the one-process solve of the whole pile; every answer is re-measured by
//! the independent error measure of `common` on the whole problem, assembled here from
//! what each process wrote.
//!
//! Each test runs this binary again on several processes (`cadmm::distributed::mpirun`),
//! each doing the work of one process.
#![cfg(feature = "mpi")]

mod common;

#[path = "../examples/extreme/scenes.rs"]
mod scenes;

use cadmm::distributed::{DistributedSolver, RankProblem};
use cadmm::{GlobalProblem, LinearSolver, Problem, Settings, Solver, Status};
use mpi::traits::Communicator;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};

/// Where a child writes its answer, and which pile it solves.
const OUT: &str = "CADMM_MPI_OUT";
const PILE: &str = "CADMM_MPI_PILE";
const TOLERANCE: f64 = 1e-6;

/// The piles of the tests, of about a thousand contacts each.
fn pile(name: &str) -> scenes::Scene {
    match name {
        "lattice" => scenes::pile(12, 8, 4),
        "irregular" => scenes::irregular_pile(12, 10, 4),
        "islands" => piles_apart(),
        _ => panic!("unknown pile {name}"),
    }
}

/// Small lattice piles standing apart, at x positions inside one slab each on 2 and on 4
/// processes but one (x 5 to 6), which straddles the slabs' border at x 5.5, and two free
/// bodies at x 0 and 11 that fix the slabs' widths (the test's x range is 0 to 11). Each
/// process has islands of its own; on 4 processes two have no contact in the shared
/// problem.
fn piles_apart() -> scenes::Scene {
    let mut scene = scenes::Scene::default();
    for (k, x) in [0.5, 3.0, 5.0, 6.5, 9.0].into_iter().enumerate() {
        let small = scenes::pile(2, 2, 3);
        let (dx, dy) = (x, 4.0 * k as f64);
        let first = scene.bodies.len();
        for mut b in small.bodies {
            b.x = [b.x[0] + dx, b.x[1] + dy, b.x[2]];
            scene.bodies.push(b);
        }
        for mut c in small.contacts {
            c.a += first;
            c.b = c.b.map(|b| b + first);
            c.point = [c.point[0] + dx, c.point[1] + dy, c.point[2]];
            scene.contacts.push(c);
        }
    }
    for x in [0.0, 11.0] {
        scene.body(1.0, [0.1; 3], [x, -10.0, 5.0]);
    }
    scene
}

/// The slab of each body and contact on `size` processes: bodies by their x position in
/// equal widths, each contact with its first body.
fn slabs(scene: &scenes::Scene, size: usize) -> (Vec<usize>, Vec<usize>) {
    let x = |b: &scenes::Body| b.x[0];
    let lo = scene.bodies.iter().map(x).fold(f64::INFINITY, f64::min);
    let hi = scene.bodies.iter().map(x).fold(f64::NEG_INFINITY, f64::max);
    let width = (hi - lo).max(1e-9) / size as f64;
    let body_rank: Vec<usize> = scene
        .bodies
        .iter()
        .map(|b| (((x(b) - lo) / width) as usize).min(size - 1))
        .collect();
    let contact_rank = scene.contacts.iter().map(|c| body_rank[c.a]).collect();
    (body_rank, contact_rank)
}

fn settings() -> Settings {
    Settings {
        tolerance: TOLERANCE,
        ..Settings::default()
    }
}

/// Runs this binary's test `name` on `np` processes, solving `pile` and writing into
/// `out`; their output.
fn mpirun(name: &str, np: usize, pile: &str, out: &Path) -> String {
    std::fs::create_dir_all(out).unwrap();
    let env = [(OUT, out.as_os_str()), (PILE, OsStr::new(pile))];
    cadmm::distributed::mpirun::run(name, np, &env)
}

fn scratch(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cadmm-distributed-{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// What the processes wrote: the whole pile's impulses and velocities, and each
/// process's file as it was (for the bitwise comparison).
struct Answer {
    r: Vec<f64>,
    v: Vec<f64>,
    files: Vec<String>,
    statuses: Vec<String>,
    /// Contacts in the shared problem, all processes together.
    shared: usize,
}

fn read_answer(dir: &Path, np: usize, p: &GlobalProblem) -> Answer {
    let mut answer = Answer {
        r: vec![f64::NAN; p.w.len()],
        v: vec![f64::NAN; p.n()],
        files: Vec::new(),
        statuses: Vec::new(),
        shared: 0,
    };
    for rank in 0..np {
        let text = std::fs::read_to_string(dir.join(format!("rank-{rank}.txt"))).unwrap();
        for line in text.lines() {
            let words: Vec<&str> = line.split_whitespace().collect();
            let bits = |w: &str| f64::from_bits(u64::from_str_radix(w, 16).unwrap());
            match words[0] {
                "contact" => {
                    let c: usize = words[1].parse().unwrap();
                    for k in 0..3 {
                        answer.r[3 * c + k] = bits(words[2 + k]);
                    }
                }
                "body" => {
                    let b: usize = words[1].parse().unwrap();
                    for k in 0..6 {
                        answer.v[6 * b + k] = bits(words[2 + k]);
                    }
                }
                "shared" => answer.shared += words[1].parse::<usize>().unwrap(),
                _ => answer.statuses.push(words[1..].join(" ")),
            }
        }
        answer.files.push(text);
    }
    assert!(
        answer.r.iter().chain(&answer.v).all(|x| !x.is_nan()),
        "every contact and body has an answer from one process"
    );
    answer
}

/// `||a - b|| / scale`.
fn difference(a: &[f64], b: &[f64], scale: f64) -> f64 {
    let diff: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
    diff.sqrt() / scale
}

/// `||M^-1 f||`, the velocities' scale without contacts (the piles' M is diagonal).
fn free_velocity(p: &GlobalProblem) -> f64 {
    let mut sq = 0.0;
    for j in 0..p.n() {
        let diagonal: Vec<(usize, f64)> = p.m.col(j).collect();
        assert_eq!(diagonal.len(), 1, "a diagonal M");
        sq += (p.f[j] / diagonal[0].1).powi(2);
    }
    sq.sqrt()
}

fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

#[test]
fn piles_split_into_slabs_solve_as_one_process() {
    let name = "piles_split_into_slabs_solve_as_one_process";
    if cadmm::distributed::mpirun::is_child() {
        return child();
    }
    for kind in ["lattice", "irregular", "islands"] {
        let p = pile(kind).global();
        // The one-process solver by both backends: how far apart two of its own answers
        // to the tolerance are (a pile at rest is ill-conditioned, its solutions to 1e-6
        // far apart) sets how close the distributed answers must come.
        let one = |backend| {
            let settings = Settings {
                linear_solver: backend,
                ..settings()
            };
            let mut one = Solver::new(Problem::Global(p.clone()), settings).unwrap();
            assert_eq!(one.solve().unwrap(), Status::Solved, "{kind}: one process");
            let s = one.solution().clone();
            let e_one = common::global_error_sparse(&p, &s.r, &s.v);
            assert!(e_one <= TOLERANCE, "{kind}: one process, error {e_one:e}");
            (s, one.stats().islands)
        };
        let ((reference, islands), (direct, _)) =
            (one(LinearSolver::Iterative), one(LinearSolver::Direct));
        let spread = difference(&direct.v, &reference.v, free_velocity(&p));
        let mut files = Vec::new();
        for (np, tag) in [(1, "a"), (2, "a"), (4, "a"), (2, "b")] {
            let dir = scratch(&format!("{kind}-{np}-{tag}"));
            mpirun(name, np, kind, &dir);
            let answer = read_answer(&dir, np, &p);
            let _ = std::fs::remove_dir_all(&dir);
            assert!(
                answer.statuses.iter().all(|s| s.starts_with("Solved")),
                "{kind} on {np}: {:?}",
                answer.statuses
            );
            // Every process reports the same iterations and error.
            assert!(answer.statuses.windows(2).all(|s| s[0] == s[1]));
            let error = common::global_error_sparse(&p, &answer.r, &answer.v);
            assert!(error <= TOLERANCE, "{kind} on {np}: error {error:e}");
            // Both answers meet the tolerance; how far apart they are, on the scales of
            // the velocities without contacts and of the impulses.
            let dv = difference(&answer.v, &reference.v, free_velocity(&p));
            let dr = difference(&answer.r, &reference.r, norm(&reference.r));
            println!(
                "{kind} ({} contacts) on {np} processes: {}, error {error:.2e}; \
                 against one process: v {dv:.1e}, r {dr:.1e} (its own backends: v {spread:.1e})",
                p.n_contacts(),
                answer.statuses[0]
            );
            assert!(
                dv <= (2.0 * spread).max(100.0 * TOLERANCE),
                "{kind} on {np}: v differs by {dv:e}, the one-process backends by {spread:e}"
            );
            // Islands inside one process are solved there: the shared problem holds only
            // the islands that straddle processes (here, of the piles apart, the one over
            // x 5.5: 24 contacts).
            assert!(
                answer.statuses[0].ends_with(&format!("islands {islands}")),
                "{kind} on {np}: {} (one process: {islands} islands)",
                answer.statuses[0]
            );
            if kind == "islands" {
                assert_eq!(
                    answer.shared,
                    if np == 1 { 0 } else { 24 },
                    "{kind} on {np}"
                );
            }
            files.push((np, answer.files));
        }
        // Two runs on two processes: bitwise the same.
        let twos: Vec<_> = files.iter().filter(|(np, _)| *np == 2).collect();
        assert_eq!(
            twos[0].1, twos[1].1,
            "{kind}: two runs on 2 processes differ"
        );
    }
}

/// One process's part of the test: solves its slab of the pile and writes its contacts'
/// impulses and bodies' velocities, bit for bit.
fn child() {
    let universe = mpi::initialize().expect("MPI starts");
    let world = universe.world();
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let scene = pile(&std::env::var(PILE).unwrap());
    let p = scene.global();
    let (body_rank, contact_rank) = slabs(&scene, size);
    let dofs = vec![6; scene.bodies.len()];
    let part = RankProblem::split(&p, &dofs, &body_rank, &contact_rank, rank).unwrap();
    let mut solver = DistributedSolver::new(&world, part.clone(), settings()).unwrap();
    let status = solver.solve().unwrap();
    let stats = solver.stats();
    let hex = |x: &[f64]| {
        x.iter()
            .map(|v| format!("{:016x}", v.to_bits()))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let mut text = format!(
        "status {status:?} {} iterations error {:e} islands {}\n",
        stats.iterations, stats.error, stats.islands
    );
    text += &format!("shared {}\n", solver.n_shared_contacts());
    let contacts = (0..contact_rank.len()).filter(|&c| contact_rank[c] == rank);
    for (k, c) in contacts.enumerate() {
        text += &format!("contact {c} {}\n", hex(&solver.r()[3 * k..3 * k + 3]));
    }
    for (k, &id) in part.bodies.iter().enumerate() {
        text += &format!("body {id} {}\n", hex(&solver.v()[6 * k..6 * k + 6]));
    }
    let dir = PathBuf::from(std::env::var_os(OUT).unwrap());
    std::fs::write(dir.join(format!("rank-{rank}.txt")), text).unwrap();
}

/// Settings that differ between processes: before, the processes hung (in the solve for
/// another tolerance, limit or variant, already in `new` for islands on one and off on the
/// other). Now `new` refuses them on every process, naming the setting and the ranks.
#[test]
fn settings_that_differ_between_processes_are_refused() {
    let name = "settings_that_differ_between_processes_are_refused";
    if cadmm::distributed::mpirun::is_child() {
        return settings_child();
    }
    for case in ["tolerance", "max_iterations", "variant", "islands"] {
        let dir = scratch(&format!("settings-{case}"));
        mpirun(name, 2, case, &dir);
        for rank in 0..2 {
            let said = std::fs::read_to_string(dir.join(format!("rank-{rank}.txt"))).unwrap();
            assert!(
                said.starts_with("InvalidSetting")
                    && said.contains(&format!("invalid setting {case}:"))
                    && said.contains("rank 0 has")
                    && said.contains("rank 1 has"),
                "{case}, rank {rank}: {said}"
            );
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// One process of [`settings_that_differ_between_processes_are_refused`]: rank 1 changes
/// the setting the case names; each process writes what `new` said.
fn settings_child() {
    let universe = mpi::initialize().expect("MPI starts");
    let world = universe.world();
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let scene = pile("islands");
    let p = scene.global();
    let (body_rank, contact_rank) = slabs(&scene, size);
    let part = RankProblem::split(
        &p,
        &vec![6; scene.bodies.len()],
        &body_rank,
        &contact_rank,
        rank,
    )
    .unwrap();
    let mut s = settings();
    if rank == 1 {
        match std::env::var(PILE).unwrap().as_str() {
            "tolerance" => s.tolerance = 1e-10,
            "max_iterations" => s.max_iterations = 77,
            "variant" => s.variant = cadmm::VariantChoice::from_name("vp-RR-He").unwrap(),
            _ => s.islands = false,
        }
    }
    let said = match DistributedSolver::new(&world, part, s) {
        Ok(_) => "built".to_string(),
        Err(e) => format!("{:?}: {}", e.kind, e.message),
    };
    let dir = PathBuf::from(std::env::var_os(OUT).unwrap());
    std::fs::write(dir.join(format!("rank-{rank}.txt")), said).unwrap();
}
