//! `cadmm_csc`: a borrowed compressed-column matrix passed in from C.

use super::arrays::{check_len, check_ptr, input};
use super::result::{Failure, FfiResult, CADMM_ERR_INVALID_CSC};
use crate::csc::CscMatrix;

/// A sparse matrix in compressed sparse column form, 0-based, borrowed for the duration of
/// the call that receives it (the library copies what it keeps).
///
/// `colptr` (never NULL) has `ncols + 1` entries, starts at 0 and does not decrease;
/// `rowind` and `values` have `colptr[ncols]` entries each (NULL allowed when that is 0).
/// Row indices lie in `[0, nrows)`, need not be sorted within a column, and must not repeat
/// within a column. Values must be finite. Symmetric matrices (M, W) are given in full, both
/// triangles.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct cadmm_csc {
    /// Number of rows.
    pub nrows: usize,
    /// Number of columns.
    pub ncols: usize,
    /// Column pointers, `ncols + 1` entries.
    pub colptr: *const i64,
    /// Row index of each entry, `colptr[ncols]` entries.
    pub rowind: *const i64,
    /// Value of each entry, `colptr[ncols]` entries.
    pub values: *const f64,
}

fn invalid(field: &str, reason: String) -> Failure {
    Failure::new(
        CADMM_ERR_INVALID_CSC,
        format!("invalid CSC matrix {field}: {reason}"),
    )
}

/// Copies and validates a C matrix. `field` names it in errors (`"M"`, `"H"`...).
///
/// The column pointers are validated before `rowind` and `values` are read, so a corrupt
/// `colptr` cannot make the library read past the caller's arrays.
///
/// # Safety
/// `m`, if non-NULL, must point to a `cadmm_csc` whose arrays have the lengths documented
/// on the type.
pub(crate) unsafe fn read_csc(field: &'static str, m: *const cadmm_csc) -> FfiResult<CscMatrix> {
    check_ptr(field, m)?;
    // SAFETY: checked non-NULL and aligned; a plain-old-data copy.
    let m = unsafe { m.read() };
    let ncols1 = m
        .ncols
        .checked_add(1)
        .ok_or_else(|| invalid(field, format!("ncols = {} is too large", m.ncols)))?;
    check_len::<i64>(field, ncols1)?;
    // SAFETY: ncols + 1 entries by contract (never zero, so NULL is refused).
    let colptr_c = unsafe { input(&format!("{field}.colptr"), m.colptr, ncols1)? };
    let mut colptr = Vec::with_capacity(ncols1);
    for (j, &p) in colptr_c.iter().enumerate() {
        let p = usize::try_from(p)
            .map_err(|_| invalid(field, format!("colptr[{j}] = {p} is negative")))?;
        if j == 0 && p != 0 {
            return Err(invalid(field, format!("colptr[0] = {p}, expected 0")));
        }
        if let Some(&prev) = colptr.last() {
            if p < prev {
                return Err(invalid(
                    field,
                    format!("column pointers decrease at column {}", j - 1),
                ));
            }
        }
        colptr.push(p);
    }
    let nnz = colptr[m.ncols];
    // SAFETY: nnz entries each by contract (NULL allowed only when nnz == 0).
    let rowind_c = unsafe { input(&format!("{field}.rowind"), m.rowind, nnz)? };
    // SAFETY: as above.
    let values = unsafe { input(&format!("{field}.values"), m.values, nnz)? };
    let rowind = rowind_c
        .iter()
        .enumerate()
        .map(|(k, &i)| {
            usize::try_from(i)
                .map_err(|_| invalid(field, format!("row index {i} at entry {k} is negative")))
        })
        .collect::<FfiResult<Vec<usize>>>()?;
    Ok(CscMatrix::new(
        field,
        m.nrows,
        m.ncols,
        colptr,
        rowind,
        values.to_vec(),
    )?)
}
