"""The exceptions cadmm raises: one class per result code of the C API.

Every class derives from :class:`cadmm.Error`; those about a bad argument also derive from
:class:`ValueError`, so ``except ValueError`` catches them as it would any numpy or scipy
complaint about an argument.
"""


class Error(Exception):
    """Base class of cadmm's exceptions."""


class DimensionError(Error, ValueError):
    """Two sizes that must agree do not (a matrix shape, a vector length). ``CADMM_ERR_DIMENSION``."""


class InvalidCscError(Error, ValueError):
    """A compressed-column matrix is malformed (pointers, indices, duplicates). ``CADMM_ERR_INVALID_CSC``."""


class InvalidValueError(Error, ValueError):
    """A value is NaN, infinite or out of range (a negative friction coefficient). ``CADMM_ERR_INVALID_VALUE``."""


class NotPositiveDefiniteError(Error, ValueError):
    """A matrix that must be positive definite (``M``, ``W + rho I``) is not. ``CADMM_ERR_NOT_POSITIVE_DEFINITE``."""


class SingularError(Error, ValueError):
    """The factorization of a non-symmetric matrix failed: it is singular. ``CADMM_ERR_SINGULAR``."""


class InvalidSettingError(Error, ValueError):
    """A setting is unknown or out of range, or cannot change in a built solver. ``CADMM_ERR_INVALID_SETTING``."""


class PatternChangedError(Error, ValueError):
    """New values do not have the sparsity pattern the solver was built for. ``CADMM_ERR_PATTERN_CHANGED``."""


class OutOfMemoryError(Error, MemoryError):
    """Memory for a system or its factorization could not be allocated. ``CADMM_ERR_OUT_OF_MEMORY``."""


class UnsupportedError(Error):
    """The operation does not apply (new values of the other form's fields). ``CADMM_ERR_UNSUPPORTED``."""


class IoError(Error, OSError):
    """Reading or writing a file failed, or it is not an FCLib problem. ``CADMM_ERR_IO``."""


__all__ = [
    "Error",
    "DimensionError",
    "InvalidCscError",
    "InvalidValueError",
    "NotPositiveDefiniteError",
    "SingularError",
    "InvalidSettingError",
    "PatternChangedError",
    "OutOfMemoryError",
    "UnsupportedError",
    "IoError",
]
