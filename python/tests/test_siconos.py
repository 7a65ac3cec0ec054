"""A few FCLib problems solved by Siconos numerics (its Python module, from python3-siconos)
and by cadmm, both answers judged by the same independent measure."""

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import cadmm
from conftest import FCLIB, require
from measure import error as measured

TOLERANCE = 1e-8
FILES = [
    "local/FC3D_Example1.hdf5",
    "local/Capsules-i100-889.hdf5",
    "local/KaplasTower-i1061-4.hdf5",
    "global/GFC3D_Example1.hdf5",
    "global/Box_Stacks-i0122-82-5.hdf5",
]

# Siconos runs in a process of its own: its wrappers share memory with numpy in ways that
# are safest ended by the process.
SICONOS = textwrap.dedent(
    """
    import json, os, sys
    import numpy as np
    import siconos.numerics as sn

    def sparse(data, name):
        # Compressed columns with the 64-bit indices of Siconos' sparse storage.
        import scipy.sparse as sp
        parts = (data[name + "_x"], data[name + "_i"].astype(np.int64), data[name + "_p"].astype(np.int64))
        return sp.csc_matrix(parts, shape=tuple(data[name + "_shape"]))

    data = np.load(sys.argv[1])
    tolerance = float(sys.argv[2])
    sn.numerics_set_verbose(0)
    mu = np.ascontiguousarray(data["mu"])
    r, u = np.zeros(3 * len(mu)), np.zeros(3 * len(mu))
    if "W" in data:
        problem = sn.FrictionContactProblem(3, np.ascontiguousarray(data["W"]), np.ascontiguousarray(data["q"]), mu)
        options = sn.SolverOptions(sn.SICONOS_FRICTION_3D_NSGS)
        solve = lambda: sn.fc3d_driver(problem, r, u, options)
        v = None
    else:
        problem = sn.GlobalFrictionContactProblem()
        problem.dimension, problem.numberOfContacts = 3, len(mu)
        problem.M = sparse(data, "M")
        problem.H = sparse(data, "H")  # before b, whose size it sets
        problem.q = np.ascontiguousarray(data["f"])
        problem.b = np.ascontiguousarray(data["w"])
        problem.mu = mu
        options = sn.SolverOptions(sn.SICONOS_GLOBAL_FRICTION_3D_NSGS_WR)
        v = np.zeros(len(data["f"]))
        solve = lambda: sn.gfc3d_driver(problem, r, u, v, options)
    options.iparam[sn.SICONOS_IPARAM_MAX_ITER] = 20000
    options.dparam[sn.SICONOS_DPARAM_TOL] = tolerance
    info = solve()
    out = {"info": int(info), "r": r.tolist(), "v": None if v is None else v.tolist()}
    print(json.dumps(out), flush=True)
    os._exit(0)
    """
)


def siconos_available() -> bool:
    found = subprocess.run([sys.executable, "-c", "import siconos.numerics"], capture_output=True)
    return found.returncode == 0


def solve_with_siconos(problem, tmp_path):
    arrays = {"mu": problem.mu}
    if isinstance(problem, cadmm.LocalProblem):
        arrays.update(W=problem.W.toarray(), q=problem.q)
    else:
        for name, m in (("M", problem.M), ("H", problem.H)):
            arrays.update({name + "_x": m.data, name + "_i": m.indices, name + "_p": m.indptr,
                           name + "_shape": np.array(m.shape)})
        arrays.update(f=problem.f, w=problem.w)
    np.savez(tmp_path / "problem.npz", **arrays)
    done = subprocess.run(
        [sys.executable, "-c", SICONOS, str(tmp_path / "problem.npz"), str(TOLERANCE)],
        capture_output=True, text=True, timeout=300,
    )
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout.strip().splitlines()[-1])
    return np.array(out["r"]), None if out["v"] is None else np.array(out["v"])


@pytest.mark.parametrize("name", FILES)
def test_same_answer_as_siconos_by_the_common_measure(name, tmp_path):
    require(siconos_available(), "Siconos numerics' Python module (python3-siconos) is not importable")
    path = FCLIB / name
    require(path.exists(), f"{path} is missing")
    problem = cadmm.read_fclib(path)
    solver = cadmm.Solver(problem, cadmm.Settings(tolerance=TOLERANCE))
    assert solver.solve() == cadmm.Status.SOLVED
    s = solver.solution
    is_global = isinstance(problem, cadmm.GlobalProblem)
    ours = measured(problem, s.r, s.v if is_global else None)
    r, v = solve_with_siconos(problem, tmp_path)
    theirs = measured(problem, r, v)
    print(f"\n{name}: cadmm {ours:.2e}, Siconos {theirs:.2e}, "
          f"|r_cadmm - r_siconos| / |r| = {np.linalg.norm(s.r - r) / max(np.linalg.norm(r), 1e-300):.1e}")
    assert ours <= TOLERANCE * (1 + 1e-6)
    # Both answer the same problem: where Siconos reached the tolerance, so did cadmm.
    assert theirs > TOLERANCE or ours <= TOLERANCE
