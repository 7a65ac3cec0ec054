//! One pile solved across MPI processes, as a host engine would share it out: every
//! process generates the pile, keeps the bodies whose x position falls in its slab (equal
//! widths) and the contacts whose first body it owns, and hands that part to
//! `DistributedSolver`. The piles are those of `examples/scale.rs` (lattice or irregular).
//! Each process prints one JSON line: its part, its timings (setup, solve, and the share of
//! the solve spent in exchanges with the other processes, waiting included) and its peak
//! memory (before the check); the iterations, status and error are every process's.
//!
//! ```sh
//! cargo build --release --features mpi --example distributed
//! mpirun -np 2 target/release/examples/distributed --kind lattice --dims 26x26x51 --tol 1e-4
//! ```
//!
//! `--islands off` makes the whole pile the shared problem even on one process (by
//! default one process solves its islands alone, by the one-process solver).
//!
//! `cli/bench/distributed_scale.py` runs the strong and weak scaling series with it. On a
//! cluster the same command runs with a hostfile (`mpirun --hostfile hosts -np 64 ...`).

#[path = "../tests/common/mod.rs"]
mod common;
#[path = "extreme/scenes.rs"]
mod scenes;

use cadmm::distributed::{DistributedSolver, RankProblem};
use cadmm::Settings;
use mpi::traits::Communicator;
use scenes::Scene;
use std::process::ExitCode;
use std::time::Instant;

struct Args {
    kind: String,
    dims: (usize, usize, usize),
    tol: f64,
    time_limit: f64,
    /// Islands inside one process solved there (on one process: the whole pile, by the
    /// one-process solver); off, the whole pile is the shared problem.
    islands: bool,
    /// Gather the answer on process 0 and measure it on the whole problem with the
    /// independent measure of `tests/common`.
    check: bool,
}

fn parse() -> Result<Args, String> {
    let mut args = Args {
        kind: "lattice".into(),
        dims: (10, 10, 10),
        tol: 1e-4,
        time_limit: f64::INFINITY,
        islands: true,
        check: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        if flag == "--check" {
            args.check = true;
            continue;
        }
        let value = it.next().ok_or(format!("{flag} needs a value"))?;
        match flag.as_str() {
            "--kind" if value == "lattice" || value == "irregular" => args.kind = value,
            "--dims" => {
                let d: Vec<usize> = value
                    .split('x')
                    .map(|x| x.parse().map_err(|e| format!("--dims {value}: {e}")))
                    .collect::<Result<_, _>>()?;
                let [x, y, z] = d[..] else {
                    return Err(format!("--dims {value}: three sizes, NXxNYxNZ"));
                };
                args.dims = (x, y, z);
            }
            "--tol" => args.tol = value.parse().map_err(|e| format!("--tol: {e}"))?,
            "--islands" if value == "on" || value == "off" => args.islands = value == "on",
            "--time-limit" => {
                args.time_limit = value.parse().map_err(|e| format!("--time-limit: {e}"))?
            }
            _ => return Err(format!("unknown argument {flag} {value}")),
        }
    }
    Ok(args)
}

/// The slab of each body on `size` processes (by x position, equal widths).
fn body_ranks(scene: &Scene, size: usize) -> Vec<usize> {
    let lo = scene
        .bodies
        .iter()
        .map(|b| b.x[0])
        .fold(f64::INFINITY, f64::min);
    let hi = scene
        .bodies
        .iter()
        .map(|b| b.x[0])
        .fold(f64::NEG_INFINITY, f64::max);
    let width = (hi - lo).max(1e-9) / size as f64;
    scene
        .bodies
        .iter()
        .map(|b| (((b.x[0] - lo) / width) as usize).min(size - 1))
        .collect()
}

/// This process's part: its contacts with the bodies they touch, assembled as a problem of
/// their own, cut by [`RankProblem::split`], then named by the bodies' global indices.
fn part(scene: &Scene, body_rank: &[usize], rank: usize) -> RankProblem {
    let contacts: Vec<_> = scene
        .contacts
        .iter()
        .filter(|c| body_rank[c.a] == rank)
        .cloned()
        .collect();
    let mut global = Vec::new();
    let mut local = std::collections::HashMap::new();
    let mut keep = |b: usize| {
        *local.entry(b).or_insert_with(|| {
            global.push(b);
            global.len() - 1
        })
    };
    for (b, &r) in body_rank.iter().enumerate() {
        if r == rank {
            keep(b);
        }
    }
    let contacts: Vec<_> = contacts
        .into_iter()
        .map(|mut c| {
            c.a = keep(c.a);
            c.b = c.b.map(&mut keep);
            c
        })
        .collect();
    let sub = Scene {
        bodies: global.iter().map(|&b| scene.bodies[b].clone()).collect(),
        contacts,
    };
    let ranks: Vec<usize> = global.iter().map(|&b| body_rank[b]).collect();
    let mut part = RankProblem::split(
        &sub.global(),
        &vec![6; global.len()],
        &ranks,
        &vec![rank; sub.contacts.len()],
        rank,
    )
    .expect("a pile's part");
    for id in part.bodies.iter_mut().chain(&mut part.h_body) {
        *id = global[*id as usize] as u64;
    }
    part
}

/// Every process's `values` (`width` per item, items named by `ids`) in the whole
/// problem's order, on every process (all-gather: the check is not a timed part).
fn gather(world: &impl Communicator, values: &[f64], ids: &[u64], width: usize) -> Vec<f64> {
    use mpi::datatype::PartitionMut;
    use mpi::traits::CommunicatorCollectives;
    let size = world.size() as usize;
    let mut counts = vec![0i32; size];
    world.all_gather_into(&(ids.len() as i32), &mut counts[..]);
    let displs: Vec<i32> = counts
        .iter()
        .scan(0, |at, &n| {
            let d = *at;
            *at += n;
            Some(d)
        })
        .collect();
    let total = counts.iter().sum::<i32>() as usize;
    let mut all_ids = vec![0u64; total];
    world.all_gather_varcount_into(
        ids,
        &mut PartitionMut::new(&mut all_ids[..], &counts[..], &displs[..]),
    );
    let wide: Vec<i32> = counts.iter().map(|n| n * width as i32).collect();
    let wide_displs: Vec<i32> = displs.iter().map(|d| d * width as i32).collect();
    let mut all = vec![0.0; total * width];
    world.all_gather_varcount_into(
        values,
        &mut PartitionMut::new(&mut all[..], &wide[..], &wide_displs[..]),
    );
    let mut out = vec![0.0; total * width];
    for (k, &id) in all_ids.iter().enumerate() {
        let id = id as usize;
        out[width * id..width * (id + 1)].copy_from_slice(&all[width * k..width * (k + 1)]);
    }
    out
}

/// Peak resident memory of this process (Linux `VmHWM`), in MB.
fn peak_mb() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn main() -> ExitCode {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("distributed: {e}");
            return ExitCode::from(2);
        }
    };
    let universe = mpi::initialize().expect("MPI starts");
    let world = universe.world();
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let (x, y, z) = args.dims;
    let scene = match args.kind.as_str() {
        "lattice" => scenes::pile(x, y, z),
        _ => scenes::irregular_pile(x, y, z),
    };
    let body_rank = body_ranks(&scene, size);
    let mine = part(&scene, &body_rank, rank);
    let total = scene.contacts.len();
    let ids = mine.bodies.clone();
    let contact_ids: Vec<u64> = (0..total)
        .filter(|&c| body_rank[scene.contacts[c].a] == rank)
        .map(|c| c as u64)
        .collect();
    let scene = args.check.then_some(scene);
    let owned = mine.n_contacts();
    let settings = Settings {
        tolerance: args.tol,
        time_limit: args.time_limit,
        islands: args.islands,
        ..Settings::default()
    };
    let t0 = Instant::now();
    let mut solver = match DistributedSolver::new(&world, mine, settings) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("distributed: {e}");
            return ExitCode::FAILURE;
        }
    };
    let setup = t0.elapsed().as_secs_f64();
    let status = match solver.solve() {
        Ok(s) => s,
        Err(e) => {
            eprintln!("distributed: {e}");
            return ExitCode::FAILURE;
        }
    };
    let peak = peak_mb();
    let checked = args.check.then(|| {
        let r = gather(&world, solver.r(), &contact_ids, 3);
        let v = gather(&world, solver.v(), &ids, 6);
        (rank == 0).then(|| {
            let whole = scene.as_ref().expect("kept for the check").global();
            common::global_error_sparse(&whole, &r, &v)
        })
    });
    let s = solver.stats();
    println!(
        "{{\"kind\": \"{}\", \"dims\": \"{x}x{y}x{z}\", \"processes\": {size}, \"rank\": {rank}, \
         \"contacts\": {total}, \"owned_contacts\": {owned}, \"status\": \"{status:?}\", \
         \"iterations\": {}, \"linear_iterations\": {}, \"error\": {:e}, \"setup_seconds\": {setup:.4}, \
         \"solve_seconds\": {:.4}, \"exchange_seconds\": {:.4}, \"peak_mb\": {:.1}, \"checked_error\": {}}}",
        args.kind,
        s.iterations,
        s.linear_iterations,
        s.error,
        s.solve_seconds,
        solver.exchange_seconds(),
        peak,
        match checked.flatten() {
            Some(e) => format!("{e:e}"),
            None => "null".into(),
        }
    );
    ExitCode::SUCCESS
}
