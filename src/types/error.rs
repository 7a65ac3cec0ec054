//! Typed errors of the library.

use std::fmt;

/// Why a call failed. Every variant names what was wrong; none of them is a solve outcome
/// (see [`super::Status`] for that).
#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// Two sizes that must agree do not (`field` is the offending argument).
    Dimension {
        /// Argument whose size is wrong.
        field: &'static str,
        /// Size that was expected.
        expected: usize,
        /// Size that was given.
        found: usize,
    },
    /// A compressed-column matrix has an invalid structure.
    InvalidCsc {
        /// Matrix name (`M`, `H`, `G`, `W`).
        field: &'static str,
        /// What is wrong, with the index.
        reason: String,
    },
    /// A value is NaN, infinite or out of its range (negative friction coefficient...).
    InvalidValue {
        /// Argument that holds the value.
        field: &'static str,
        /// Index of the value inside the argument.
        index: usize,
        /// What is wrong.
        reason: &'static str,
    },
    /// A matrix that must be positive definite (M, `M + rho H H^T`, `W + rho I`) is not.
    NotPositiveDefinite {
        /// Matrix that failed to factorize.
        field: &'static str,
    },
    /// The factorization of a (non-symmetric) matrix failed: singular.
    Singular {
        /// Matrix that failed to factorize.
        field: &'static str,
    },
    /// A setting is out of range or unknown.
    InvalidSetting {
        /// Setting name.
        name: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// A new problem or new values for a solver do not have the sparsity pattern the
    /// solver was built for (same sizes, other non-zero positions).
    PatternChanged {
        /// Matrix whose pattern differs (`M`, `H`, `G`, `W`).
        field: &'static str,
    },
    /// Memory for a system or its factorization could not be allocated.
    OutOfMemory {
        /// What was being built.
        what: String,
    },
    /// The operation does not apply here (e.g. FCLib I/O without the `fclib` feature).
    Unsupported(String),
    /// Reading or writing a file failed.
    Io(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Dimension {
                field,
                expected,
                found,
            } => {
                write!(
                    f,
                    "dimension mismatch in {field}: expected {expected}, found {found}"
                )
            }
            Error::InvalidCsc { field, reason } => {
                write!(f, "invalid CSC matrix {field}: {reason}")
            }
            Error::InvalidValue {
                field,
                index,
                reason,
            } => {
                write!(f, "invalid value in {field}[{index}]: {reason}")
            }
            Error::NotPositiveDefinite { field } => write!(f, "{field} is not positive definite"),
            Error::Singular { field } => write!(f, "{field} is singular"),
            Error::InvalidSetting { name, reason } => write!(f, "invalid setting {name}: {reason}"),
            Error::PatternChanged { field } => write!(
                f,
                "the sparsity pattern of {field} differs from the one the solver was built for"
            ),
            Error::OutOfMemory { what } => write!(f, "out of memory: {what}"),
            Error::Unsupported(what) => write!(f, "unsupported: {what}"),
            Error::Io(what) => write!(f, "i/o error: {what}"),
        }
    }
}

impl std::error::Error for Error {}

/// What kind of error an [`Error`] is, without its details: the C API's result code, and
/// what the processes sharing a distributed problem learn of one process's error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// [`Error::Dimension`].
    Dimension,
    /// [`Error::InvalidCsc`].
    InvalidCsc,
    /// [`Error::InvalidValue`].
    InvalidValue,
    /// [`Error::NotPositiveDefinite`].
    NotPositiveDefinite,
    /// [`Error::Singular`].
    Singular,
    /// [`Error::InvalidSetting`].
    InvalidSetting,
    /// [`Error::PatternChanged`].
    PatternChanged,
    /// [`Error::OutOfMemory`].
    OutOfMemory,
    /// [`Error::Unsupported`].
    Unsupported,
    /// [`Error::Io`].
    Io,
}

impl ErrorKind {
    /// Every kind, in a fixed order (a kind's index there is how it travels between
    /// processes).
    pub const ALL: [ErrorKind; 10] = [
        Self::Dimension,
        Self::InvalidCsc,
        Self::InvalidValue,
        Self::NotPositiveDefinite,
        Self::Singular,
        Self::InvalidSetting,
        Self::PatternChanged,
        Self::OutOfMemory,
        Self::Unsupported,
        Self::Io,
    ];
}

impl Error {
    /// The kind of this error.
    pub fn kind(&self) -> ErrorKind {
        match self {
            Error::Dimension { .. } => ErrorKind::Dimension,
            Error::InvalidCsc { .. } => ErrorKind::InvalidCsc,
            Error::InvalidValue { .. } => ErrorKind::InvalidValue,
            Error::NotPositiveDefinite { .. } => ErrorKind::NotPositiveDefinite,
            Error::Singular { .. } => ErrorKind::Singular,
            Error::InvalidSetting { .. } => ErrorKind::InvalidSetting,
            Error::PatternChanged { .. } => ErrorKind::PatternChanged,
            Error::OutOfMemory { .. } => ErrorKind::OutOfMemory,
            Error::Unsupported(_) => ErrorKind::Unsupported,
            Error::Io(_) => ErrorKind::Io,
        }
    }
}
