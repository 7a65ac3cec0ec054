"""Type stubs of the compiled extension module (re-exported by ``cadmm``)."""

from typing import Any, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

from .status import Status

__version__: str

# Any scipy.sparse matrix or array, or anything numpy reads as a 2-D float array.
MatrixLike = Any
VectorLike = npt.ArrayLike
Vector = npt.NDArray[np.float64]

class GlobalProblem:
    """``M v = H r + G lambda + f``, ``u = H^T v + w``, Coulomb cones ``mu``; joint rows ``G^T v + b + compliance lambda``, bounded by ``lo <= lambda <= hi`` and, with ``friction_contact[k] >= 0``, by ``|lambda_k| <= friction[k] r_n`` of that contact (rolling and spinning friction)."""

    def __init__(
        self,
        M: MatrixLike,
        H: MatrixLike,
        f: VectorLike,
        w: VectorLike,
        mu: VectorLike,
        G: Optional[MatrixLike] = None,
        b: Optional[VectorLike] = None,
        *,
        lo: Optional[VectorLike] = None,
        hi: Optional[VectorLike] = None,
        compliance: Optional[VectorLike] = None,
        friction_contact: Optional[Sequence[int]] = None,
        friction: Optional[VectorLike] = None,
    ) -> None: ...
    @property
    def n(self) -> int: ...
    @property
    def n_contacts(self) -> int: ...
    @property
    def n_joints(self) -> int: ...
    @property
    def M(self) -> Any: ...
    @property
    def H(self) -> Any: ...
    @property
    def G(self) -> Optional[Any]: ...
    @property
    def f(self) -> Vector: ...
    @property
    def w(self) -> Vector: ...
    @property
    def mu(self) -> Vector: ...
    @property
    def b(self) -> Optional[Vector]: ...

class LocalProblem:
    """``u = W r + q``, Coulomb cones ``mu``."""

    def __init__(self, W: MatrixLike, q: VectorLike, mu: VectorLike) -> None: ...
    @property
    def n_contacts(self) -> int: ...
    @property
    def W(self) -> Any: ...
    @property
    def q(self) -> Vector: ...
    @property
    def mu(self) -> Vector: ...

Problem = Union[GlobalProblem, LocalProblem]

class Settings:
    """Settings of a solve, each validated when set (``InvalidSettingError``)."""

    def __init__(
        self,
        *,
        tolerance: Optional[float] = None,
        max_iterations: Optional[int] = None,
        time_limit: Optional[float] = None,
        variant: Optional[str] = None,
        linear_solver: Optional[str] = None,
        threads: Optional[int] = None,
    ) -> None: ...
    tolerance: float
    max_iterations: int
    time_limit: float
    variant: str
    linear_solver: str
    threads: int

class Solution:
    """The answer of a solve (copies)."""

    @property
    def r(self) -> Vector: ...
    @property
    def u(self) -> Vector: ...
    @property
    def v(self) -> Vector: ...
    @property
    def lambda_(self) -> Vector: ...

class Stats:
    """Statistics of a solve."""

    @property
    def status(self) -> Status: ...
    @property
    def iterations(self) -> int: ...
    @property
    def error(self) -> float: ...
    @property
    def primal_residual(self) -> float: ...
    @property
    def dual_residual(self) -> float: ...
    @property
    def rho(self) -> float: ...
    @property
    def refactorizations(self) -> int: ...
    @property
    def newton_iterations(self) -> int: ...
    @property
    def islands(self) -> int: ...
    @property
    def setup_seconds(self) -> float: ...
    @property
    def solve_seconds(self) -> float: ...

class Solver:
    """Solves a problem, and its successors with the same sparsity patterns."""

    def __init__(self, problem: Problem, settings: Optional[Settings] = None) -> None: ...
    def solve(self) -> Status: ...
    @property
    def solution(self) -> Solution: ...
    @property
    def stats(self) -> Stats: ...
    def update_values(
        self,
        *,
        M: Optional[MatrixLike] = None,
        H: Optional[MatrixLike] = None,
        G: Optional[MatrixLike] = None,
        f: Optional[VectorLike] = None,
        w: Optional[VectorLike] = None,
        b: Optional[VectorLike] = None,
        mu: Optional[VectorLike] = None,
        W: Optional[MatrixLike] = None,
        q: Optional[VectorLike] = None,
        lo: Optional[VectorLike] = None,
        hi: Optional[VectorLike] = None,
        compliance: Optional[VectorLike] = None,
        friction: Optional[VectorLike] = None,
    ) -> None: ...
    def warm_start(self, r: VectorLike, v: Optional[VectorLike] = None) -> None: ...
    def update_settings(self, settings: Settings) -> None: ...
    def rebuild(self, problem: Problem) -> None: ...

def error(
    problem: Problem,
    r: VectorLike,
    u: Optional[VectorLike] = None,
    v: Optional[VectorLike] = None,
    lambda_: Optional[VectorLike] = None,
) -> float: ...
