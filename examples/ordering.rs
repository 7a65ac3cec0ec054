//! Fill-reducing orderings for the sparse Cholesky factor of the ADMM velocity update,
//! `K = M + rho H H^T` of a global problem: approximate minimum degree (AMD, the ordering
//! the solver's factorization uses) against nested dissection (METIS `NodeND`, passed to
//! the symbolic analysis as a custom ordering).
//!
//! `rho = trace(M) / trace(H H^T)`, so that both terms weigh the same. Joints are left
//! out and local problems are skipped. One Markdown table row per file and ordering:
//!
//! - `n`, `nnz(K)`: size and stored entries of K's upper triangle;
//! - `nnz(L)`: entries of the Cholesky factor (simplicial analysis, diagonal included);
//!   `stored`: the values the factorization actually stores (supernodal blocks padded);
//! - `order+symb`: ordering and symbolic analysis (for nested dissection: building the
//!   graph, METIS, and the analysis); `metis`: the METIS call alone;
//! - `numeric`: median of 5 numeric factorizations; `solve`: one solve with one
//!   right-hand side, and the relative residual of that solve. Times in milliseconds.
//!
//! ```sh
//! cargo run --release --features fclib --example ordering -- FILES...
//! ```

use cadmm::{GlobalProblem, Problem};
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, MatMut, Par, Side};
use metis_sys as m;
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// Upper triangle of a symmetric matrix.
type Upper = SparseColMat<usize, f64>;

/// Upper triangle of `K = M + rho H H^T`, and rho.
fn v_update_matrix(p: &GlobalProblem) -> (Upper, f64) {
    let (mass, h) = (&p.m, &p.h);
    let n = mass.ncols();
    let trace_m: f64 = (0..n)
        .flat_map(|j| mass.col(j).filter(move |&(i, _)| i == j))
        .map(|(_, v)| v)
        .sum();
    let trace_hht: f64 = h.values().iter().map(|v| v * v).sum();
    let rho = if trace_hht > 0.0 {
        trace_m / trace_hht
    } else {
        1.0
    };
    let mut entries = Vec::new();
    for j in 0..n {
        let upper = mass.col(j).filter(|&(i, _)| i <= j);
        entries.extend(upper.map(|(i, v)| Triplet::new(i, j, v)));
    }
    // Column c of H adds rho h_c h_c^T; its rows are sorted, so pairs (a <= b) are upper.
    for c in 0..h.ncols() {
        let col: Vec<(usize, f64)> = h.col(c).collect();
        for (a, &(i, hi)) in col.iter().enumerate() {
            entries.extend(
                col[a..]
                    .iter()
                    .map(|&(j, hj)| Triplet::new(i, j, rho * hi * hj)),
            );
        }
    }
    let k = SparseColMat::try_new_from_triplets(n, n, &entries).expect("K fits in memory");
    (k, rho)
}

/// METIS nested dissection of K's graph: the forward (new to old) and inverse
/// permutations, and the time of the METIS call.
fn metis_order(k: &Upper) -> (Vec<usize>, Vec<usize>, Duration) {
    let n = k.nrows();
    // Adjacency of both triangles, without the diagonal, in compressed form.
    let edges = || {
        (0..n).flat_map(move |j| {
            k.symbolic()
                .row_idx_of_col_raw(j)
                .iter()
                .filter(move |&&i| i != j)
                .map(move |&i| (i, j))
        })
    };
    let mut xadj = vec![0 as m::idx_t; n + 1];
    for (i, j) in edges() {
        xadj[i + 1] += 1;
        xadj[j + 1] += 1;
    }
    for v in 1..=n {
        xadj[v] += xadj[v - 1];
    }
    let mut next: Vec<usize> = xadj[..n].iter().map(|&x| x as usize).collect();
    let mut adjncy = vec![0 as m::idx_t; xadj[n] as usize];
    for (i, j) in edges() {
        adjncy[next[i]] = j as m::idx_t;
        adjncy[next[j]] = i as m::idx_t;
        next[i] += 1;
        next[j] += 1;
    }
    let mut options = [0 as m::idx_t; m::METIS_NOPTIONS as usize];
    let mut nvtxs = n as m::idx_t;
    let (mut perm, mut iperm) = (vec![0 as m::idx_t; n], vec![0 as m::idx_t; n]);
    let start = Instant::now();
    // SAFETY: every array has the length METIS expects (n + 1, 2 * edges, NOPTIONS, n, n)
    // and outlives the calls; no vertex weights.
    let status = unsafe {
        m::METIS_SetDefaultOptions(options.as_mut_ptr());
        options[m::moptions_et_METIS_OPTION_NUMBERING as usize] = 0;
        m::METIS_NodeND(
            &mut nvtxs,
            xadj.as_mut_ptr(),
            adjncy.as_mut_ptr(),
            std::ptr::null_mut(),
            options.as_mut_ptr(),
            perm.as_mut_ptr(),
            iperm.as_mut_ptr(),
        )
    };
    let time = start.elapsed();
    assert_eq!(status, m::rstatus_et_METIS_OK, "METIS_NodeND failed");
    // METIS: row i of the permuted matrix is row perm[i] of K (faer's forward array).
    let to_usize = |p: Vec<m::idx_t>| p.into_iter().map(|x| x as usize).collect();
    (to_usize(perm), to_usize(iperm), time)
}

/// Measurements of one ordering.
struct Row {
    nnz_l: usize,
    stored: usize,
    symbolic: Duration,
    numeric: Duration,
    solve: Duration,
    residual: f64,
}

/// Symbolic analysis with `ordering`, 5 numeric factorizations and one solve.
fn measure(k: &Upper, ordering: SymmetricOrdering<'_, usize>) -> Row {
    let n = k.nrows();
    let start = Instant::now();
    let s = factorize_symbolic_cholesky(k.symbolic(), Side::Upper, ordering, Default::default())
        .expect("symbolic analysis");
    let symbolic = start.elapsed();
    let simplicial = CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
        ..Default::default()
    };
    let nnz_l = factorize_symbolic_cholesky(k.symbolic(), Side::Upper, ordering, simplicial)
        .expect("symbolic analysis")
        .len_val();
    let mut mem = MemBuffer::new(StackReq::any_of(&[
        s.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        s.solve_in_place_scratch::<f64>(1, Par::Seq),
    ]));
    let mut l = vec![0.0; s.len_val()];
    let mut times: Vec<Duration> = (0..5)
        .map(|_| {
            let start = Instant::now();
            s.factorize_numeric_llt(
                &mut l,
                k.as_ref(),
                Side::Upper,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .expect("K is positive definite");
            start.elapsed()
        })
        .collect();
    times.sort();
    let b = vec![1.0; n];
    let mut x = b.clone();
    let start = Instant::now();
    LltRef::new(&s, &l).solve_in_place_with_conj(
        Conj::No,
        MatMut::from_column_major_slice_mut(&mut x, n, 1),
        Par::Seq,
        MemStack::new(&mut mem),
    );
    let solve = start.elapsed();
    Row {
        nnz_l,
        stored: s.len_val(),
        symbolic,
        numeric: times[2],
        solve,
        residual: relative_residual(k, &x, &b),
    }
}

/// `|K x - b| / |b|` with K given by its upper triangle.
fn relative_residual(k: &Upper, x: &[f64], b: &[f64]) -> f64 {
    let mut r: Vec<f64> = b.iter().map(|v| -v).collect();
    for j in 0..k.ncols() {
        let rows = k.symbolic().row_idx_of_col_raw(j);
        for (&i, &v) in rows.iter().zip(k.val_of_col(j)) {
            r[i] += v * x[j];
            if i != j {
                r[j] += v * x[i];
            }
        }
    }
    let norm = |v: &[f64]| v.iter().map(|a| a * a).sum::<f64>().sqrt();
    norm(&r) / norm(b)
}

fn ms(d: Duration) -> String {
    format!("{:.3}", d.as_secs_f64() * 1e3)
}

fn main() -> ExitCode {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        eprintln!("usage: ordering FILE.hdf5...");
        return ExitCode::FAILURE;
    }
    println!(
        "| file | n | nnz(K) | rho | ordering | nnz(L) | stored | order+symb | metis \
         | numeric | solve | residual |"
    );
    println!("|---|--:|--:|--:|---|--:|--:|--:|--:|--:|--:|--:|");
    for path in &paths {
        let p = match cadmm::fclib::read(path) {
            Ok(Problem::Global(p)) => p,
            Ok(Problem::Local(_)) => {
                eprintln!("{path}: local problem, skipped");
                continue;
            }
            Err(e) => {
                eprintln!("{path}: {e}");
                return ExitCode::FAILURE;
            }
        };
        let name = std::path::Path::new(path).file_stem().unwrap_or_default();
        let (k, rho) = v_update_matrix(&p);
        let n = k.nrows();
        let amd = measure(&k, SymmetricOrdering::Amd);
        let start = Instant::now();
        let (fwd, inv, metis) = metis_order(&k);
        let graph_and_metis = start.elapsed();
        let mut nd = measure(
            &k,
            SymmetricOrdering::Custom(PermRef::new_checked(&fwd, &inv, n)),
        );
        nd.symbolic += graph_and_metis;
        for (label, row, metis) in [("AMD", amd, None), ("METIS ND", nd, Some(metis))] {
            println!(
                "| {} | {n} | {} | {rho:.3e} | {label} | {} | {} | {} | {} | {} | {} | {:.1e} |",
                name.to_string_lossy(),
                k.compute_nnz(),
                row.nnz_l,
                row.stored,
                ms(row.symbolic),
                metis.map_or("-".into(), ms),
                ms(row.numeric),
                ms(row.solve),
                row.residual,
            );
        }
    }
    ExitCode::SUCCESS
}
