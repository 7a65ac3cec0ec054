"""Every shared FCLib problem, solved and measured again by the independent measure."""

import pytest

import cadmm
from conftest import FCLIB, fclib_files, require
from measure import error as measured

TOLERANCE = 1e-8
# The solver stops at its own measure <= tolerance; an independent evaluation of the same
# formula may differ by round-off.
ROUND_OFF = 1e-12


def test_the_problems_are_there():
    require(len(fclib_files()) > 0, f"no FCLib problems in {FCLIB}")


@pytest.mark.parametrize("path", fclib_files(), ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_solved_and_measured_again(path):
    pytest.importorskip("h5py")
    problem = cadmm.read_fclib(path)
    solver = cadmm.Solver(problem, cadmm.Settings(tolerance=TOLERANCE))
    assert solver.solve() == cadmm.Status.SOLVED
    s = solver.solution
    v = s.v if isinstance(problem, cadmm.GlobalProblem) else None
    again = measured(problem, s.r, v)
    assert again <= TOLERANCE + ROUND_OFF, f"{path.name}: measured again {again:.3e}"
    assert again == pytest.approx(solver.stats.error, rel=1e-6, abs=ROUND_OFF)
