"""One contact on the ground, whose answers are known in closed form, and the solver's API
around it: dense and sparse input, warm start, updates, settings, FCLib round trip."""

import re

import numpy as np
import pytest
import scipy.sparse as sp

import cadmm
from measure import error as measured

MU = 0.5
G = 9.81


def ground(push: float, form: str = "global"):
    """A unit mass pressed on the ground by gravity and pushed sideways by ``push``:
    the free velocity is (-G, push, 0) in the contact frame (normal first)."""
    free = np.array([-G, push, 0.0])
    if form == "global":
        return cadmm.GlobalProblem(np.eye(3), sp.identity(3, format="csr"), free, np.zeros(3), [MU])
    return cadmm.LocalProblem(np.eye(3), free, [MU])


@pytest.mark.parametrize("form", ["global", "local"])
def test_sticking(form):
    p = ground(1.0, form)  # 1 < mu G: friction holds the mass
    s = cadmm.Solver(p)
    assert s.solve() == cadmm.Status.SOLVED
    np.testing.assert_allclose(s.solution.r, [G, -1.0, 0.0], atol=1e-7)
    np.testing.assert_allclose(s.solution.u, 0.0, atol=1e-7)
    assert s.stats.error <= 1e-8


@pytest.mark.parametrize("form", ["global", "local"])
def test_sliding(form):
    p = ground(10.0, form)  # 10 > mu G: slides, friction at the cone's edge
    s = cadmm.Solver(p)
    assert s.solve() == cadmm.Status.SOLVED
    np.testing.assert_allclose(s.solution.r, [G, -MU * G, 0.0], atol=1e-7)
    np.testing.assert_allclose(s.solution.u, [0.0, 10.0 - MU * G, 0.0], atol=1e-7)
    if form == "global":
        np.testing.assert_allclose(s.solution.v, s.solution.u, atol=1e-7)


def test_separating_contact_has_no_impulse():
    p = cadmm.GlobalProblem(np.eye(3), np.eye(3), [1.0, 2.0, 0.0], np.zeros(3), [MU])
    s = cadmm.Solver(p)
    assert s.solve() == cadmm.Status.SOLVED
    np.testing.assert_allclose(s.solution.r, 0.0, atol=1e-12)
    np.testing.assert_allclose(s.solution.v, [1.0, 2.0, 0.0])


def test_every_matrix_input_gives_the_same_problem():
    dense = np.diag([2.0, 3.0, 4.0])
    for m in (dense, dense.tolist(), sp.csr_matrix(dense), sp.coo_array(dense), sp.lil_matrix(dense)):
        p = cadmm.GlobalProblem(m, np.eye(3), [-G, 1.0, 0.0], np.zeros(3), [MU])
        np.testing.assert_array_equal(p.M.toarray(), dense)


def test_error_agrees_with_the_independent_measure():
    p = ground(10.0)
    s = cadmm.Solver(p)
    s.solve()
    r, v = s.solution.r, s.solution.v
    for rr, vv in ((r, v), (r * 1.1, v + 0.01), (np.zeros(3), np.zeros(3))):
        assert cadmm.error(p, rr, v=vv) == pytest.approx(measured(p, rr, vv), rel=1e-12, abs=1e-15)


def test_warm_start_from_the_answer_needs_no_iteration():
    p = ground(10.0)
    s = cadmm.Solver(p, cadmm.Settings(variant="cp-N"))
    s.solve()
    cold = s.stats.iterations
    s.warm_start(s.solution.r, s.solution.v)
    assert s.solve() == cadmm.Status.SOLVED
    assert s.stats.iterations < cold


def test_update_values_is_the_next_problem():
    s = cadmm.Solver(ground(1.0))
    s.solve()
    s.update_values(f=[-G, 10.0, 0.0], M=sp.identity(3) * 1.0)
    assert s.solve() == cadmm.Status.SOLVED
    np.testing.assert_allclose(s.solution.r, [G, -MU * G, 0.0], atol=1e-7)
    with pytest.raises(cadmm.PatternChangedError):
        s.update_values(M=np.ones((3, 3)))
    with pytest.raises(cadmm.UnsupportedError):
        s.update_values(q=[0.0, 0.0, 0.0])


def test_rebuild_takes_a_problem_of_another_pattern():
    # With and without a time limit (the sweeps then built in the memory they replace): a
    # box on the ground, then two contacts on the same rows (they stick, r_a + r_b = -f),
    # then the box again; a refused problem (an indefinite M) changes nothing.
    for settings in (cadmm.Settings(), cadmm.Settings(time_limit=10.0)):
        s = cadmm.Solver(ground(1.0), settings)
        h2 = sp.hstack([sp.identity(3), sp.identity(3)]).tocsc()
        two = cadmm.GlobalProblem(np.eye(3), h2, [-G, 0.1, 0.0], np.zeros(6), [MU, MU])
        s.rebuild(two)
        assert s.solve() == cadmm.Status.SOLVED
        r = s.solution.r
        np.testing.assert_allclose(r[:3] + r[3:], [G, -0.1, 0.0], atol=1e-7)
        np.testing.assert_allclose(s.solution.v, np.zeros(3), atol=1e-7)
        m = np.diag([1.0, -1.0, 1.0])
        indefinite = cadmm.GlobalProblem(m, sp.identity(3, format="csr"), [-G, 0.1, 0.0], np.zeros(3), [MU])
        with pytest.raises(cadmm.NotPositiveDefiniteError):
            s.rebuild(indefinite)
        assert s.solve() == cadmm.Status.SOLVED
        assert len(s.solution.r) == 6
        s.rebuild(ground(1.0))
        assert s.solve() == cadmm.Status.SOLVED
        assert len(s.solution.r) == 3
        s.update_values(f=[-G, 10.0, 0.0], M=sp.identity(3) * 1.0)
        assert s.solve() == cadmm.Status.SOLVED
        np.testing.assert_allclose(s.solution.r, [G, -MU * G, 0.0], atol=1e-7)


def test_settings_are_validated_when_set():
    s = cadmm.Settings(tolerance=1e-6, max_iterations=50, time_limit=2.0, variant="vp-RR-He", threads=2)
    assert (s.tolerance, s.max_iterations, s.time_limit, s.variant, s.threads) == (1e-6, 50, 2.0, "vp-RR-He", 2)
    assert s.linear_solver == "auto" and cadmm.Settings().time_limit == float("inf")
    with pytest.raises(cadmm.InvalidSettingError):
        s.tolerance = 0.0
    assert s.tolerance == 1e-6  # a refused value changes nothing
    with pytest.raises(cadmm.InvalidSettingError):
        s.variant = "fast"
    with pytest.raises(cadmm.InvalidSettingError):
        cadmm.Settings(linear_solver="gmres")


def test_update_settings_takes_limits_and_refuses_structure():
    s = cadmm.Solver(ground(1.0))
    s.update_settings(cadmm.Settings(tolerance=1e-10, max_iterations=10))
    assert s.solve() in (cadmm.Status.SOLVED, cadmm.Status.MAX_ITERATIONS)
    with pytest.raises(cadmm.InvalidSettingError):
        s.update_settings(cadmm.Settings(variant="cp-N"))


def test_stats_before_and_after_a_solve():
    s = cadmm.Solver(ground(1.0))
    assert s.stats.status == cadmm.Status.UNSOLVED
    s.solve()
    assert s.stats.status == cadmm.Status.SOLVED and s.stats.iterations >= 1
    assert str(cadmm.Status.SOLVED) == "Status.SOLVED"


def test_fclib_round_trip(tmp_path):
    pytest.importorskip("h5py")
    for p in (ground(10.0), ground(1.0, "local")):
        path = tmp_path / "p.hdf5"
        cadmm.write_fclib(p, path)
        q = cadmm.read_fclib(path)
        assert type(q) is type(p)
        s = cadmm.Solver(q)
        assert s.solve() == cadmm.Status.SOLVED
    joints = cadmm.GlobalProblem(np.eye(3), np.eye(3), [-G, 0, 0], np.zeros(3), [MU], G=np.eye(3)[:, :1])
    cadmm.write_fclib(joints, tmp_path / "j.hdf5")
    back = cadmm.read_fclib(tmp_path / "j.hdf5")
    assert back.n_joints == 1 and back.b.tolist() == [0.0]


def test_version_is_the_library_version():
    from conftest import ROOT

    text = (ROOT / "Cargo.toml").read_text()
    assert re.search(r'^version = "([^"]+)"', text, re.M).group(1) == cadmm.__version__
