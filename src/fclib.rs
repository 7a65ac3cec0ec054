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

/// A size a matrix must have, and where it comes from (for the message).
#[derive(Clone, Copy)]
struct Expected {
    size: usize,
    from: &'static str,
}

/// Checks a size field of matrix `name` (`m` or `n`) against what the problem's vectors
/// say, before it sizes anything: a corrupt field must give an error naming it, not an
/// allocation of its claimed size.
fn check_size(
    path: &Path,
    name: &str,
    field: &str,
    found: usize,
    e: Expected,
) -> Result<(), Error> {
    if found != e.size {
        return Err(io(
            path,
            format!(
                "matrix {name}: {field} = {found}, expected {} ({})",
                e.size, e.from
            ),
        ));
    }
    Ok(())
}

fn read_matrix(
    parent: &Group,
    name: &'static str,
    path: &Path,
    rows: Expected,
    cols: Expected,
) -> Result<CscMatrix, Error> {
    let g = parent
        .group(name)
        .map_err(|e| io(path, format!("matrix {name}: {e}")))?;
    let nrows = index(scalar(&g, "m", path)?, "row count", path)?;
    let ncols = index(scalar(&g, "n", path)?, "column count", path)?;
    check_size(path, name, "m", nrows, rows)?;
    check_size(path, name, "n", ncols, cols)?;
    let nz = scalar(&g, "nz", path)?;
    let stored = Stored {
        name,
        path,
        nrows,
        ncols,
        p: ints(&g, "p", path)?,
        i: ints(&g, "i", path)?,
        x: floats(&g, "x", path)?,
    };
    match nz {
        -1 => stored.by_columns(),
        -2 => stored.by_rows(),
        nz if nz >= 0 => stored.triplets(nz as usize),
        other => Err(io(
            path,
            format!("matrix {name}: unknown encoding nz = {other}"),
        )),
    }
}

/// A matrix's arrays as the file stores them, in one of FCLib's three encodings.
struct Stored<'a> {
    name: &'static str,
    path: &'a Path,
    nrows: usize,
    ncols: usize,
    p: Vec<i64>,
    i: Vec<i64>,
    x: Vec<f64>,
}

impl Stored<'_> {
    fn indices(&self, v: &[i64], what: &str) -> Result<Vec<usize>, Error> {
        v.iter().map(|&k| index(k, what, self.path)).collect()
    }

    /// Refuses `p` announcing more entries than `i` and `x` hold.
    fn check_entries(&self, nnz: usize) -> Result<(), Error> {
        if self.i.len() < nnz || self.x.len() < nnz {
            return Err(io(
                self.path,
                format!(
                    "matrix {}: p announces {nnz} entries, i holds {} and x holds {}",
                    self.name,
                    self.i.len(),
                    self.x.len()
                ),
            ));
        }
        Ok(())
    }

    /// Compressed columns (`nz = -1`): `p` column pointers, `i` row indices.
    fn by_columns(&self) -> Result<CscMatrix, Error> {
        let (name, ncols) = (self.name, self.ncols);
        if self.p.len() != ncols + 1 {
            return Err(io(
                self.path,
                format!(
                    "matrix {name}: n = {ncols} but p holds {} column pointers",
                    self.p.len()
                ),
            ));
        }
        let colptr = self.indices(&self.p, "column pointer")?;
        let nnz = *colptr.last().unwrap_or(&0);
        self.check_entries(nnz)?;
        CscMatrix::new(
            name,
            self.nrows,
            ncols,
            colptr,
            self.indices(&self.i[..nnz], "row index")?,
            self.x[..nnz].to_vec(),
        )
    }

    /// Compressed rows (`nz = -2`): `p` row pointers, `i` column indices.
    fn by_rows(&self) -> Result<CscMatrix, Error> {
        let (name, nrows) = (self.name, self.nrows);
        let rowptr = self.indices(&self.p, "row pointer")?;
        if rowptr.len() != nrows + 1 {
            return Err(io(
                self.path,
                format!(
                    "matrix {name}: m = {nrows} but p holds {} row pointers",
                    rowptr.len()
                ),
            ));
        }
        if let Some(r) = rowptr.windows(2).position(|w| w[1] < w[0]) {
            return Err(io(
                self.path,
                format!("matrix {name}: row pointers p decrease at row {r}"),
            ));
        }
        // Every entry needs a column index in i and a value in x.
        let nnz = rowptr[nrows];
        self.check_entries(nnz)?;
        let mut t = Vec::with_capacity(nnz);
        for r in 0..nrows {
            for k in rowptr[r]..rowptr[r + 1] {
                t.push((r, index(self.i[k], "column index", self.path)?, self.x[k]));
            }
        }
        CscMatrix::from_triplets(name, nrows, self.ncols, &t)
    }

    /// `nz` triplets: `i` row indices, `p` column indices.
    fn triplets(&self, nz: usize) -> Result<CscMatrix, Error> {
        let (i, p, x) = (&self.i, &self.p, &self.x);
        if i.len() < nz || p.len() < nz || x.len() < nz {
            return Err(io(
                self.path,
                format!(
                    "matrix {}: nz = {nz} triplets announced, i holds {}, p {} and x {}",
                    self.name,
                    i.len(),
                    p.len(),
                    x.len()
                ),
            ));
        }
        let t: Result<Vec<_>, Error> = (0..nz)
            .map(|k| {
                Ok((
                    index(i[k], "row index", self.path)?,
                    index(p[k], "column index", self.path)?,
                    x[k],
                ))
            })
            .collect();
        CscMatrix::from_triplets(self.name, self.nrows, self.ncols, &t?)
    }
}

/// Refuses a path that is not a regular file before anything opens it: opening a FIFO
/// nobody writes to blocks forever, and a device could be read without end.
fn regular_file(path: &Path) -> Result<(), Error> {
    let meta = std::fs::metadata(path).map_err(|e| io(path, e))?;
    if !meta.is_file() {
        return Err(io(path, "not a regular file"));
    }
    Ok(())
}

/// Reads an FCLib problem (global or local). Read only files you trust: libhdf5 itself can
/// crash on a corrupt file (found by fuzzing) before the checks here run.
///
/// The vectors are read first: their lengths give the sizes the matrices' `m` and `n` must
/// have (`n` from `f`, the contacts from `mu`, the joints from `b`), so that a corrupt size
/// field is an i/o error naming it before it sizes anything.
pub fn read(path: impl AsRef<Path>) -> Result<Problem, Error> {
    let path = path.as_ref();
    regular_file(path)?;
    let file = File::open(path).map_err(|e| io(path, e))?;
    let contacts = |mu: &[f64]| Expected {
        size: 3 * mu.len(),
        from: "3 x the length of vectors/mu",
    };
    if let Ok(g) = file.group("fclib_global") {
        let v = g.group("vectors").map_err(|e| io(path, e))?;
        let (f, w, mu) = (
            floats(&v, "f", path)?,
            floats(&v, "w", path)?,
            floats(&v, "mu", path)?,
        );
        let n = Expected {
            size: f.len(),
            from: "the length of vectors/f",
        };
        let m = read_matrix(&g, "M", path, n, n)?;
        let h = read_matrix(&g, "H", path, n, contacts(&mu))?;
        let p = GlobalProblem::new(m, h, f, w, mu)?;
        if g.link_exists("G") {
            let b = floats(&v, "b", path)?;
            let joints = Expected {
                size: b.len(),
                from: "the length of vectors/b",
            };
            let gm = read_matrix(&g, "G", path, n, joints)?;
            return Ok(Problem::Global(p.with_joints(gm, b)?));
        }
        return Ok(Problem::Global(p));
    }
    if let Ok(g) = file.group("fclib_local") {
        let v = g.group("vectors").map_err(|e| io(path, e))?;
        let (q, mu) = (floats(&v, "q", path)?, floats(&v, "mu", path)?);
        let w = read_matrix(&g, "W", path, contacts(&mu), contacts(&mu))?;
        return Ok(Problem::Local(LocalProblem::new(w, q, mu)?));
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
    if let Problem::Global(GlobalProblem {
        joints: Some(j), ..
    }) = problem
    {
        if j.beyond_equalities() {
            return Err(Error::Unsupported(
                "write_fclib: the FCLib format holds equality joint rows only, and this \
                 problem has joint bounds or compliance"
                    .into(),
            ));
        }
    }
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
    regular_file(path)?;
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
