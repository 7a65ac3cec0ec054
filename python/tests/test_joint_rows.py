"""Bounded and compliant joint rows from Python, against closed forms.

A unit mass on the ground (M = H = I3, contact frame = world frame, normal first), pressed
down by f = (-9.81, 0, 0) with mu = 0.5 (friction holds up to 4.905), pushed along T1 by a
motor: the joint row G = e_1, b = -0.3 (target velocity 0.3), its multiplier in [-F, F].
A strong motor (F = 6) slides the block at 0.3 with lambda = 0.3 + 4.905; a weak one
(F = 3) saturates at 3 while friction holds the block (v = 0, r_T = -3). With compliance
c = 0.01 the strong motor's row reads v_1 - 0.3 + 0.01 lambda = 0 and, sliding,
lambda = v_1 + 4.905: v_1 = 0.25095 / 1.01.
"""

import numpy as np
import pytest

import cadmm

TOL = 1e-10


def block(limit, compliance=0.0):
    eye = np.eye(3)
    g = np.array([[0.0], [1.0], [0.0]])
    return cadmm.GlobalProblem(
        eye,
        eye,
        [-9.81, 0.0, 0.0],
        [0.0, 0.0, 0.0],
        [0.5],
        G=g,
        b=[-0.3],
        lo=[-limit],
        hi=[limit],
        compliance=[compliance],
    )


def solve(problem):
    solver = cadmm.Solver(problem, cadmm.Settings(tolerance=TOL))
    assert solver.solve() == cadmm.Status.SOLVED
    return solver


@pytest.mark.parametrize(
    "limit, compliance, r1, v1, lam",
    [
        (6.0, 0.0, -4.905, 0.3, 5.205),
        (3.0, 0.0, -3.0, 0.0, 3.0),
        (6.0, 0.01, -4.905, 0.25095 / 1.01, 0.25095 / 1.01 + 4.905),
    ],
)
def test_motor_against_static_friction(limit, compliance, r1, v1, lam):
    problem = block(limit, compliance)
    solver = solve(problem)
    s = solver.solution
    np.testing.assert_allclose(s.r, [9.81, r1, 0.0], atol=1e-7)
    np.testing.assert_allclose(s.v, [0.0, v1, 0.0], atol=1e-7)
    np.testing.assert_allclose(s.lambda_, [lam], atol=1e-7)
    assert cadmm.error(problem, s.r, v=s.v, lambda_=s.lambda_) <= TOL


def test_negative_control_a_multiplier_beyond_its_bound_is_measured():
    strong = solve(block(6.0)).solution
    weak = block(3.0)
    assert cadmm.error(weak, strong.r, v=strong.v, lambda_=strong.lambda_) > 1e-2


def test_update_values_takes_new_bounds():
    solver = solve(block(6.0))
    solver.update_values(lo=[-3.0], hi=[3.0])
    assert solver.solve() == cadmm.Status.SOLVED
    np.testing.assert_allclose(solver.solution.lambda_, [3.0], atol=1e-7)
    with pytest.raises(cadmm.PatternChangedError):
        solver.update_values(lo=[-np.inf], hi=[np.inf])


def test_bad_bounds_are_named():
    with pytest.raises(cadmm.InvalidValueError, match="lower bound above upper bound"):
        block(-1.0)
