//! `cadmm_csc`: a borrowed compressed-column matrix passed in from C.

use super::arrays::{check_ptr, copy, input, try_vec};
use super::result::{Failure, FfiResult, CADMM_ERR_DIMENSION, CADMM_ERR_INVALID_CSC};
use crate::csc::CscMatrix;

/// A sparse matrix in compressed sparse column form, 0-based, borrowed for the duration of
/// the call that receives it (the library copies what it keeps).
///
/// `colptr` (never NULL) has `ncols + 1` entries, starts at 0 and does not decrease;
/// `rowind` and `values` have `colptr[ncols]` entries each (NULL allowed when that is 0).
/// Row indices lie in `[0, nrows)`, need not be sorted within a column, and must not repeat
/// within a column (so a column holds at most `nrows` entries; a `colptr` saying more is
/// refused before `rowind` and `values` are read). Values must be finite. Symmetric
/// matrices (M, W) are given in full, both triangles.
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

/// The shape a matrix argument must have, from the call's other sizes.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Shape {
    /// Rows.
    pub(crate) nrows: usize,
    /// Columns; `None` for any number (the joints' G).
    pub(crate) ncols: Option<usize>,
    /// The rule in the documentation's words, for the message (e.g. `"n x 3 n_contacts"`).
    pub(crate) rule: &'static str,
}

/// Copies and validates a C matrix of the given shape. `field` names it in errors (`"M"`,
/// `"H"`...).
///
/// The sizes are compared with `shape` before anything is read or allocated, so that a
/// size contradicting the call's other sizes is refused instead of sizing an allocation
/// (an abort) or a read. The column pointers are validated before `rowind` and `values`
/// are read, and no column may hold more than `nrows` entries (duplicates are refused), so
/// a corrupt `colptr` cannot make the library read past the caller's arrays. Copies are
/// allocated fallibly (`CADMM_ERR_OUT_OF_MEMORY`).
///
/// # Safety
/// `m`, if non-NULL, must point to a `cadmm_csc` whose arrays have the lengths documented
/// on the type.
pub(crate) unsafe fn read_csc(
    field: &'static str,
    m: *const cadmm_csc,
    shape: Shape,
) -> FfiResult<CscMatrix> {
    check_ptr(field, m)?;
    // SAFETY: checked non-NULL and aligned; a plain-old-data copy.
    let m = unsafe { m.read() };
    if m.nrows != shape.nrows || shape.ncols.is_some_and(|c| c != m.ncols) {
        let ncols = shape.ncols.map_or("any".to_owned(), |c| c.to_string());
        return Err(Failure::new(
            CADMM_ERR_DIMENSION,
            format!(
                "{field} is {} x {}, expected {} x {ncols} ({})",
                m.nrows, m.ncols, shape.nrows, shape.rule
            ),
        ));
    }
    let ncols1 = m
        .ncols
        .checked_add(1)
        .ok_or_else(|| invalid(field, format!("ncols = {} is too large", m.ncols)))?;
    let colptr = unsafe { read_colptr(field, &m, ncols1)? };
    let nnz = colptr[m.ncols];
    let rowind_name = format!("{field}.rowind");
    // SAFETY: nnz entries each by contract (NULL allowed only when nnz == 0).
    let rowind_c = unsafe { input(&rowind_name, m.rowind, nnz)? };
    let mut rowind = try_vec::<usize>(&rowind_name, nnz)?;
    for (k, &i) in rowind_c.iter().enumerate() {
        let i = usize::try_from(i)
            .map_err(|_| invalid(field, format!("row index {i} at entry {k} is negative")))?;
        rowind.push(i);
    }
    // SAFETY: as above.
    let values = unsafe { copy(&format!("{field}.values"), m.values, nnz)? };
    Ok(CscMatrix::new(
        field, m.nrows, m.ncols, colptr, rowind, values,
    )?)
}

/// The `ncols + 1` column pointers of `m`, checked before they size or index anything:
/// non-negative, starting at 0, never decreasing, at most `nrows` entries a column (more
/// is a duplicate or a pointer past the caller's arrays).
///
/// # Safety
/// `m.colptr` is NULL or points to `ncols1 = m.ncols + 1` readable entries.
unsafe fn read_colptr(field: &'static str, m: &cadmm_csc, ncols1: usize) -> FfiResult<Vec<usize>> {
    let colptr_name = format!("{field}.colptr");
    check_ptr(&colptr_name, m.colptr)?;
    let mut colptr = try_vec::<usize>(&colptr_name, ncols1)?;
    // SAFETY: ncols + 1 entries by contract (non-NULL, checked above).
    let colptr_c = unsafe { input(&colptr_name, m.colptr, ncols1)? };
    if let Some(most) = m.nrows.checked_mul(m.ncols) {
        let last = colptr_c[m.ncols];
        if usize::try_from(last).is_ok_and(|last| last > most) {
            return Err(invalid(
                field,
                format!(
                    "colptr[{}] = {last}, more entries than a {} x {} matrix without \
                     duplicates holds (at most {most})",
                    m.ncols, m.nrows, m.ncols
                ),
            ));
        }
    }
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
            if p - prev > m.nrows {
                return Err(invalid(
                    field,
                    format!(
                        "column {} holds {} entries, more than nrows = {} (duplicates are \
                         not allowed)",
                        j - 1,
                        p - prev,
                        m.nrows
                    ),
                ));
            }
        }
        colptr.push(p);
    }
    Ok(colptr)
}
