//! FCLib HDF5 files (feature `fclib`): read `fclib_global` (with optional joints) and
//! `fclib_local` problems in their three matrix encodings, write problems and `/solution`.
//!
//! Matrix groups hold `m, n, nz, nzmax` and `p, i, x`: `nz = -1` compressed column (`p`
//! column pointers), `nz = -2` compressed row (`p` row pointers, `i` column indices),
//! `nz >= 0` triplets, where files written by Siconos put row indices in `i` and column
//! indices in `p`. Duplicate triplets are summed.

use crate::csc::CscMatrix;
use crate::problem::{GlobalProblem, LocalProblem, Problem};
use crate::types::Error;
use crate::types::Solution;
use hdf5::{Dataset, File, Group};
use std::path::Path;

fn io(path: &Path, what: impl std::fmt::Display) -> Error {
    Error::Io(format!("{}: {what}", path.display()))
}

/// Opens a dataset, refusing one that declares more elements than its file could hold
/// (64 times the file size, room for compression): a corrupt header must give an error,
/// not an allocation of its claimed size.
fn dataset(g: &Group, name: &str, path: &Path) -> Result<Dataset, Error> {
    let d = g
        .dataset(name)
        .map_err(|e| io(path, format!("{}/{name}: {e}", g.name())))?;
    let file_bytes = std::fs::metadata(path).map_or(0, |m| m.len());
    let limit = file_bytes.max(1 << 16).saturating_mul(64);
    let declared = (d.size() as u64).saturating_mul(8);
    if declared > limit {
        return Err(io(
            path,
            format!(
                "{}/{name} declares {} elements, more than the file can hold",
                g.name(),
                d.size()
            ),
        ));
    }
    Ok(d)
}

fn ints(g: &Group, name: &str, path: &Path) -> Result<Vec<i64>, Error> {
    let d = dataset(g, name, path)?;
    d.read_raw::<i64>()
        .map_err(|e| io(path, format!("{}/{name}: {e}", g.name())))
}

fn floats(g: &Group, name: &str, path: &Path) -> Result<Vec<f64>, Error> {
    let d = dataset(g, name, path)?;
    d.read_raw::<f64>()
        .map_err(|e| io(path, format!("{}/{name}: {e}", g.name())))
}

fn scalar(g: &Group, name: &str, path: &Path) -> Result<i64, Error> {
    ints(g, name, path)?
        .first()
        .copied()
        .ok_or_else(|| io(path, format!("{}/{name} is empty", g.name())))
}

fn index(v: i64, what: &str, path: &Path) -> Result<usize, Error> {
    usize::try_from(v).map_err(|_| io(path, format!("negative {what} {v}")))
}

fn read_matrix(parent: &Group, name: &'static str, path: &Path) -> Result<CscMatrix, Error> {
    let g = parent
        .group(name)
        .map_err(|e| io(path, format!("matrix {name}: {e}")))?;
    let nrows = index(scalar(&g, "m", path)?, "row count", path)?;
    let ncols = index(scalar(&g, "n", path)?, "column count", path)?;
    let nz = scalar(&g, "nz", path)?;
    let p = ints(&g, "p", path)?;
    let i = ints(&g, "i", path)?;
    let x = floats(&g, "x", path)?;
    let to_usize = |v: &[i64], what: &str| -> Result<Vec<usize>, Error> {
        v.iter().map(|&k| index(k, what, path)).collect()
    };
    match nz {
        -1 => {
            let colptr = to_usize(&p, "column pointer")?;
            let nnz = *colptr.last().unwrap_or(&0);
            if i.len() < nnz || x.len() < nnz {
                return Err(io(
                    path,
                    format!("matrix {name}: {nnz} entries announced, fewer stored"),
                ));
            }
            CscMatrix::new(
                name,
                nrows,
                ncols,
                colptr,
                to_usize(&i[..nnz], "row index")?,
                x[..nnz].to_vec(),
            )
        }
        -2 => {
            let rowptr = to_usize(&p, "row pointer")?;
            if rowptr.len() != nrows + 1 {
                return Err(io(
                    path,
                    format!(
                        "matrix {name}: {} row pointers for {nrows} rows",
                        rowptr.len()
                    ),
                ));
            }
            let mut t = Vec::new();
            for r in 0..nrows {
                for k in rowptr[r]..rowptr[r + 1] {
                    let c = i
                        .get(k)
                        .copied()
                        .ok_or_else(|| io(path, format!("matrix {name}: short index array")))?;
                    t.push((r, index(c, "column index", path)?, x[k]));
                }
            }
            CscMatrix::from_triplets(name, nrows, ncols, &t)
        }
        nz if nz >= 0 => {
            let nz = nz as usize;
            if i.len() < nz || p.len() < nz || x.len() < nz {
                return Err(io(
                    path,
                    format!("matrix {name}: {nz} triplets announced, fewer stored"),
                ));
            }
            let t: Result<Vec<_>, Error> = (0..nz)
                .map(|k| {
                    Ok((
                        index(i[k], "row index", path)?,
                        index(p[k], "column index", path)?,
                        x[k],
                    ))
                })
                .collect();
            CscMatrix::from_triplets(name, nrows, ncols, &t?)
        }
        other => Err(io(
            path,
            format!("matrix {name}: unknown encoding nz = {other}"),
        )),
    }
}

/// Reads an FCLib problem (global or local). Read only files you trust: libhdf5 itself can
/// crash on a corrupt file (found by fuzzing) before the checks here run.
pub fn read(path: impl AsRef<Path>) -> Result<Problem, Error> {
    let path = path.as_ref();
    let file = File::open(path).map_err(|e| io(path, e))?;
    if let Ok(g) = file.group("fclib_global") {
        let v = g.group("vectors").map_err(|e| io(path, e))?;
        let m = read_matrix(&g, "M", path)?;
        let h = read_matrix(&g, "H", path)?;
        let p = GlobalProblem::new(
            m,
            h,
            floats(&v, "f", path)?,
            floats(&v, "w", path)?,
            floats(&v, "mu", path)?,
        )?;
        if g.link_exists("G") {
            let gm = read_matrix(&g, "G", path)?;
            return Ok(Problem::Global(p.with_joints(gm, floats(&v, "b", path)?)?));
        }
        return Ok(Problem::Global(p));
    }
    if let Ok(g) = file.group("fclib_local") {
        let v = g.group("vectors").map_err(|e| io(path, e))?;
        let w = read_matrix(&g, "W", path)?;
        return Ok(Problem::Local(LocalProblem::new(
            w,
            floats(&v, "q", path)?,
            floats(&v, "mu", path)?,
        )?));
    }
    Err(io(path, "neither an fclib_global nor an fclib_local group"))
}

fn write_vec(g: &Group, name: &str, data: &[f64], path: &Path) -> Result<(), Error> {
    g.new_dataset_builder()
        .with_data(data)
        .create(name)
        .map_err(|e| io(path, format!("{name}: {e}")))?;
    Ok(())
}

fn write_ints(g: &Group, name: &str, data: &[i32], path: &Path) -> Result<(), Error> {
    g.new_dataset_builder()
        .with_data(data)
        .create(name)
        .map_err(|e| io(path, format!("{name}: {e}")))?;
    Ok(())
}

fn write_matrix(parent: &Group, name: &str, a: &CscMatrix, path: &Path) -> Result<(), Error> {
    let g = parent.create_group(name).map_err(|e| io(path, e))?;
    let int = |v: usize| {
        i32::try_from(v).map_err(|_| {
            io(
                path,
                format!("matrix {name} is too large for FCLib's int32"),
            )
        })
    };
    write_ints(&g, "m", &[int(a.nrows())?], path)?;
    write_ints(&g, "n", &[int(a.ncols())?], path)?;
    write_ints(&g, "nz", &[-1], path)?;
    write_ints(&g, "nzmax", &[int(a.nnz())?], path)?;
    let p: Result<Vec<i32>, Error> = a.colptr().iter().map(|&v| int(v)).collect();
    let i: Result<Vec<i32>, Error> = a.rowind().iter().map(|&v| int(v)).collect();
    write_ints(&g, "p", &p?, path)?;
    write_ints(&g, "i", &i?, path)?;
    write_vec(&g, "x", a.values(), path)
}

/// Writes a problem as an FCLib file (matrices in compressed-column form), replacing `path`.
pub fn write_problem(path: impl AsRef<Path>, problem: &Problem) -> Result<(), Error> {
    let path = path.as_ref();
    let file = File::create(path).map_err(|e| io(path, e))?;
    match problem {
        Problem::Global(p) => {
            let g = file.create_group("fclib_global").map_err(|e| io(path, e))?;
            write_ints(&g, "spacedim", &[3], path)?;
            write_matrix(&g, "M", &p.m, path)?;
            write_matrix(&g, "H", &p.h, path)?;
            let v = g.create_group("vectors").map_err(|e| io(path, e))?;
            write_vec(&v, "f", &p.f, path)?;
            write_vec(&v, "w", &p.w, path)?;
            write_vec(&v, "mu", &p.mu, path)?;
            if let Some(j) = &p.joints {
                write_matrix(&g, "G", &j.g, path)?;
                write_vec(&v, "b", &j.b, path)?;
            }
        }
        Problem::Local(p) => {
            let g = file.create_group("fclib_local").map_err(|e| io(path, e))?;
            write_ints(&g, "spacedim", &[3], path)?;
            write_matrix(&g, "W", &p.w, path)?;
            let v = g.create_group("vectors").map_err(|e| io(path, e))?;
            write_vec(&v, "q", &p.q, path)?;
            write_vec(&v, "mu", &p.mu, path)?;
        }
    }
    Ok(())
}

/// Writes `/solution/{r, u, v}` (v only when non-empty; `l` for joint multipliers) into a
/// new file at `path`.
pub fn write_solution(path: impl AsRef<Path>, s: &Solution) -> Result<(), Error> {
    let path = path.as_ref();
    let file = File::create(path).map_err(|e| io(path, e))?;
    let g = file.create_group("solution").map_err(|e| io(path, e))?;
    write_vec(&g, "r", &s.r, path)?;
    write_vec(&g, "u", &s.u, path)?;
    if !s.v.is_empty() {
        write_vec(&g, "v", &s.v, path)?;
    }
    if !s.lambda.is_empty() {
        write_vec(&g, "l", &s.lambda, path)?;
    }
    Ok(())
}

/// Reads `/solution/{r, u, v, l}` (written by [`write_solution`] or by another solver in the
/// same layout); `u`, `v` and `lambda` are empty when absent, `r` is required.
pub fn read_solution(path: impl AsRef<Path>) -> Result<Solution, Error> {
    let path = path.as_ref();
    let file = File::open(path).map_err(|e| io(path, e))?;
    let g = file.group("solution").map_err(|e| io(path, e))?;
    let vector = |name: &str| -> Result<Vec<f64>, Error> {
        if !g.link_exists(name) {
            return Ok(Vec::new());
        }
        dataset(&g, name, path)?
            .read_raw::<f64>()
            .map_err(|e| io(path, format!("/solution/{name}: {e}")))
    };
    if !g.link_exists("r") {
        return Err(io(path, "no /solution/r"));
    }
    Ok(Solution {
        r: vector("r")?,
        u: vector("u")?,
        v: vector("v")?,
        lambda: vector("l")?,
    })
}
