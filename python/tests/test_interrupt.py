"""Ctrl-C stops a solve under way: SIGINT to a process solving a problem at a tolerance it
cannot reach raises KeyboardInterrupt within moments, and the solver keeps its best iterate."""

import signal
import subprocess
import sys
import textwrap
import time

from conftest import FCLIB, require

FILE = FCLIB / "global" / "Box_Stacks-i1000-548-25.hdf5"

PROGRAM = textwrap.dedent(
    f"""
    import time, cadmm
    problem = cadmm.read_fclib({str(FILE)!r})
    solver = cadmm.Solver(problem, cadmm.Settings(tolerance=1e-30, max_iterations=10**9, variant="cp-N"))
    print("solving", flush=True)
    t0 = time.perf_counter()
    try:
        solver.solve()
    except KeyboardInterrupt:
        print(f"interrupted {{time.perf_counter() - t0:.2f}} {{solver.stats.status.name}}", flush=True)
    """
)


def test_ctrl_c_stops_a_solve():
    require(FILE.exists(), f"{FILE} is missing")
    child = subprocess.Popen([sys.executable, "-c", PROGRAM], stdout=subprocess.PIPE, text=True)
    assert child.stdout.readline().strip() == "solving"
    time.sleep(0.5)
    child.send_signal(signal.SIGINT)
    out, _ = child.communicate(timeout=30)
    word, seconds, status = out.split()
    assert word == "interrupted" and status == "TIME_LIMIT"
    assert float(seconds) < 5.0
