"""How a solve ended."""

import enum


class Status(enum.IntEnum):
    """Outcome of a solve that ran; the values are the C API's ``CADMM_STATUS_*`` codes."""

    SOLVED = 0
    """The error measure reached the tolerance."""
    MAX_ITERATIONS = 1
    """The iteration limit came first; the best iterate measured is kept."""
    TIME_LIMIT = 2
    """The time limit came first (or the solve was interrupted); the best iterate measured is kept."""
    NUMERICAL_ERROR = 3
    """An iterate became non-finite; the best iterate measured is kept."""
    STALLED = 4
    """The ``newton`` variant stopped making progress; its best iterate is kept."""
    INFEASIBLE = 5
    """The problem has no solution (a contact approaches that no impulse can stop)."""
    UNSOLVED = 6
    """No solve has run yet."""

    def __str__(self) -> str:
        # The same on every Python (IntEnum's own str changed in 3.11).
        return f"Status.{self.name}"


__all__ = ["Status"]
