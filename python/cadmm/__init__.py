"""cadmm: ADMM with a semismooth Newton finish for 3D frictional contact problems.

Coulomb cones in the FCLib conventions (normal first). Build a :class:`GlobalProblem`
(``M v = H r + f``, ``u = H^T v + w``) or a :class:`LocalProblem` (``u = W r + q``) from
numpy arrays or scipy.sparse matrices, then solve it with a :class:`Solver`::

    solver = cadmm.Solver(problem, cadmm.Settings(tolerance=1e-8))
    if solver.solve() == cadmm.Status.SOLVED:
        r = solver.solution.r

A solve releases the GIL, so solvers in several threads run side by side; Ctrl-C stops a
solve between iterations.
"""

from ._cadmm import GlobalProblem, LocalProblem, Settings, Solution, Solver, Stats, __version__, error
from .errors import (
    DimensionError,
    Error,
    InvalidCscError,
    InvalidSettingError,
    InvalidValueError,
    IoError,
    NotPositiveDefiniteError,
    OutOfMemoryError,
    PatternChangedError,
    SingularError,
    UnsupportedError,
)
from .fclib import read_fclib, write_fclib
from .status import Status

__all__ = [
    "GlobalProblem",
    "LocalProblem",
    "Settings",
    "Solution",
    "Solver",
    "Stats",
    "Status",
    "error",
    "read_fclib",
    "write_fclib",
    "__version__",
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
