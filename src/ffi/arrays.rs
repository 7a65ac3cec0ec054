//! Reading C arguments: pointers, arrays whose length comes from the dimensions, strings.
//! Nothing here creates a reference to caller memory before the pointer has been checked
//! for NULL and alignment; outputs are written through raw pointers, never `&mut`, so that
//! aliased output arrays are harmless.

use super::result::{
    Failure, FfiResult, CADMM_ERR_DIMENSION, CADMM_ERR_INVALID_VALUE, CADMM_ERR_OUT_OF_MEMORY,
};
use std::ffi::{c_char, CStr};
use std::mem::size_of;

/// Checks that a pointer argument is non-NULL and aligned for `T`.
pub(crate) fn check_ptr<T>(what: &str, ptr: *const T) -> FfiResult {
    if ptr.is_null() {
        return Err(Failure::null(what));
    }
    if !ptr.is_aligned() {
        return Err(Failure::new(
            CADMM_ERR_INVALID_VALUE,
            format!("{what} is not aligned for its type"),
        ));
    }
    Ok(())
}

/// Checks that `len` elements of `T` can be addressed (at most `isize::MAX` bytes).
pub(crate) fn check_len<T>(what: &str, len: usize) -> FfiResult {
    if len > isize::MAX as usize / size_of::<T>().max(1) {
        return Err(Failure::new(
            CADMM_ERR_DIMENSION,
            format!("{what}: length {len} is too large"),
        ));
    }
    Ok(())
}

/// `3 * n_contacts`, checked.
pub(crate) fn contact_len(n_contacts: usize) -> FfiResult<usize> {
    n_contacts.checked_mul(3).ok_or_else(|| {
        Failure::new(
            CADMM_ERR_DIMENSION,
            format!("n_contacts = {n_contacts} is too large"),
        )
    })
}

/// An input array of `len` elements. A zero-length array may be NULL.
///
/// # Safety
/// A non-NULL `ptr` must point to `len` readable elements that stay unchanged while the
/// returned slice is used.
pub(crate) unsafe fn input<'a, T>(what: &str, ptr: *const T, len: usize) -> FfiResult<&'a [T]> {
    if len == 0 {
        return Ok(&[]);
    }
    check_ptr(what, ptr)?;
    check_len::<T>(what, len)?;
    // SAFETY: non-NULL, aligned, length addressable; validity is the caller's contract.
    Ok(unsafe { std::slice::from_raw_parts(ptr, len) })
}

/// An empty vector with room for `len` elements, or OUT_OF_MEMORY naming `what`: a length
/// the caller controls must never abort the host on a failed allocation.
pub(crate) fn try_vec<T>(what: &str, len: usize) -> FfiResult<Vec<T>> {
    check_len::<T>(what, len)?;
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| {
        Failure::new(
            CADMM_ERR_OUT_OF_MEMORY,
            format!("{what}: cannot allocate {len} elements"),
        )
    })?;
    Ok(v)
}

/// A copy of an input array of `len` elements ([`input`]), allocated fallibly
/// ([`try_vec`]) before the caller's array is read.
///
/// # Safety
/// As for [`input`].
pub(crate) unsafe fn copy<T: Copy>(what: &str, ptr: *const T, len: usize) -> FfiResult<Vec<T>> {
    if len > 0 {
        check_ptr(what, ptr)?;
    }
    let mut v = try_vec(what, len)?;
    // SAFETY: the caller's contract, as for `input`.
    v.extend_from_slice(unsafe { input(what, ptr, len)? });
    Ok(v)
}

/// An output array of `data.len()` elements: checked (a zero-length array may be NULL).
pub(crate) fn check_output<T>(what: &str, ptr: *mut T, len: usize) -> FfiResult {
    if len == 0 {
        return Ok(());
    }
    check_ptr(what, ptr.cast_const())?;
    check_len::<T>(what, len)
}

/// Copies `data` to an output array already accepted by [`check_output`].
///
/// # Safety
/// A non-NULL `ptr` must point to `data.len()` writable elements that do not overlap `data`.
pub(crate) unsafe fn write_output<T: Copy>(ptr: *mut T, data: &[T]) {
    if !data.is_empty() {
        // SAFETY: the caller's contract; distinct allocations (data is ours).
        unsafe { std::ptr::copy_nonoverlapping(data.as_ptr(), ptr, data.len()) };
    }
}

/// A NUL-terminated UTF-8 string argument.
///
/// # Safety
/// A non-NULL `ptr` must point to a NUL-terminated string.
pub(crate) unsafe fn utf8<'a>(
    what: &str,
    ptr: *const c_char,
    bad_code: super::result::cadmm_result,
) -> FfiResult<&'a str> {
    check_ptr(what, ptr)?;
    // SAFETY: non-NULL, NUL-terminated by the caller's contract.
    let s = unsafe { CStr::from_ptr(ptr) };
    s.to_str()
        .map_err(|_| Failure::new(bad_code, format!("{what} is not valid UTF-8")))
}

/// A NUL-terminated file path argument (any bytes on Unix, UTF-8 elsewhere).
///
/// # Safety
/// A non-NULL `ptr` must point to a NUL-terminated string.
pub(crate) unsafe fn path<'a>(what: &str, ptr: *const c_char) -> FfiResult<&'a std::path::Path> {
    check_ptr(what, ptr)?;
    // SAFETY: non-NULL, NUL-terminated by the caller's contract.
    let s = unsafe { CStr::from_ptr(ptr) };
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        Ok(std::path::Path::new(std::ffi::OsStr::from_bytes(
            s.to_bytes(),
        )))
    }
    #[cfg(not(unix))]
    {
        s.to_str().map(std::path::Path::new).map_err(|_| {
            Failure::new(
                CADMM_ERR_INVALID_VALUE,
                format!("{what} is not valid UTF-8"),
            )
        })
    }
}
