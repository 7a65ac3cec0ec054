"""Solves release the GIL: two solves in two threads against the same two one after the
other. A benchmark printout (run with -s to see it), not a timed assertion."""

import threading
import time

import cadmm
from conftest import FCLIB, require

FILE = FCLIB / "global" / "Box_Stacks-i1000-547-14.hdf5"


def solve(problem) -> cadmm.Status:
    return cadmm.Solver(problem, cadmm.Settings(tolerance=1e-8)).solve()


def test_two_threads_against_one():
    require(FILE.exists(), f"{FILE} is missing")
    problem = cadmm.read_fclib(FILE)
    t0 = time.perf_counter()
    one_after_other = [solve(problem), solve(problem)]
    sequential = time.perf_counter() - t0

    results = []
    threads = [threading.Thread(target=lambda: results.append(solve(problem))) for _ in range(2)]
    t0 = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    parallel = time.perf_counter() - t0

    assert one_after_other == results == [cadmm.Status.SOLVED] * 2
    print(
        f"\n{FILE.name}: two solves one after the other {sequential:.3f} s, "
        f"in two threads {parallel:.3f} s (x{sequential / parallel:.2f})"
    )
