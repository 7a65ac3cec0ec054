"""Rolling and spinning friction from Python, against closed forms.

A ball (mass m, radius R, I = 2/5 m R^2) on a plane whose frame has x down the slope, y
along the normal, z across; velocities (v, w). The contact at (0, -R, 0) has the velocity
(v_y, v_x + R w_z, v_z - R w_x), normal first. Its rows are w_x and w_z (rolling) and w_y
(spinning), bounded by e times the contact's normal impulse. Rolling without slipping down
a slope theta: a = 5/7 g (sin(theta) - e/R cos(theta)).
"""

import numpy as np
import pytest

import cadmm

TOL = 1e-10
G = 9.81
H = 0.01


def ball(v, slope, rolling, mass=2.0, radius=0.1):
    inertia = 0.4 * mass * radius**2
    M = np.diag([mass] * 3 + [inertia] * 3)
    gravity = np.array([G * np.sin(slope), -G * np.cos(slope), 0.0, 0.0, 0.0, 0.0])
    f = M @ v + H * mass * gravity
    Hm = np.zeros((6, 3))
    Hm[1, 0] = 1.0
    Hm[0, 1], Hm[5, 1] = 1.0, radius
    Hm[2, 2], Hm[3, 2] = 1.0, -radius
    rows = np.zeros((6, 3))
    rows[3, 0] = rows[5, 1] = rows[4, 2] = 1.0
    return cadmm.GlobalProblem(
        M, Hm, f, np.zeros(3), [1.0], G=rows, b=np.zeros(3),
        friction_contact=[0, 0, 0], friction=[rolling, rolling, 0.005],
    )


@pytest.mark.parametrize("rolling", [0.0, 0.01, 0.02])
def test_ball_rolls_at_the_predicted_rate(rolling):
    slope = np.radians(20.0)
    a = 5.0 / 7.0 * G * (np.sin(slope) - rolling / 0.1 * np.cos(slope))
    v = np.zeros(6)
    problem = ball(v, slope, rolling)
    solver = cadmm.Solver(problem, cadmm.Settings(tolerance=TOL))
    for step in range(40):
        problem = ball(v, slope, rolling)
        solver.update_values(f=problem.f)
        assert solver.solve() == cadmm.Status.SOLVED
        s = solver.solution
        assert cadmm.error(problem, s.r, v=s.v, lambda_=s.lambda_) <= TOL
        v = s.v
        assert v[0] == pytest.approx((step + 1) * H * a, rel=1e-7, abs=1e-9)


def test_coefficients_update_and_bad_rows_are_named():
    problem = ball(np.zeros(6), 0.3, 0.01)
    solver = cadmm.Solver(problem, cadmm.Settings(tolerance=TOL))
    solver.update_values(friction=[0.02, 0.02, 0.0])
    assert solver.solve() == cadmm.Status.SOLVED
    with pytest.raises(cadmm.InvalidValueError, match="negative"):
        solver.update_values(friction=[-1.0, 0.0, 0.0])
    with pytest.raises(cadmm.InvalidValueError, match="friction_contact"):
        cadmm.GlobalProblem(
            np.eye(6), np.zeros((6, 3)), np.zeros(6), np.zeros(3), [0.5],
            G=np.eye(6)[:, :1], b=[0.0], friction_contact=[-2], friction=[0.1],
        )
