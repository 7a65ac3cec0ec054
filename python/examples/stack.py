"""A stack of boxes on the ground, stepped with cadmm: the top box is pushed sideways and
slides to rest on the one below, as Coulomb friction says.

Each box is a rigid body with 6 velocities (linear, then angular, world frame); each
face-to-face contact is four points at the corners of the overlap of the two faces, with
the contact frame (normal z, tangents x and y), normal first. Moreau-Jean time stepping:
every step is one global problem

    M v+ = H r + M v + h f_ext,    u = H^T v+ + w,    w_N = gap / h,

built in numpy and scipy.sparse, solved once to 1e-8 after an update of the values (the
pattern of H never changes) and a warm start from the last step. Plots the error and the
time of each step (matplotlib) into the PNG given as argument.

    python python/examples/stack.py docs/python-stack.png
"""

import sys

import numpy as np
import scipy.sparse as sp

import cadmm

BOXES = 4
HALF = np.array([0.5, 0.5, 0.25])  # half sizes (m)
MASS = 1.0
MU = 0.5
GRAVITY = 9.81
H_STEP = 1.0 / 60.0
STEPS = 120
PUSH = 1.0  # initial velocity of the top box along x (m/s)


def mass_matrix() -> sp.csc_array:
    a, b, c = 2 * HALF
    inertia = MASS / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    return sp.csc_array(sp.diags(np.tile(np.concatenate([[MASS] * 3, inertia]), BOXES)))


def contact_points(below, above):
    """Corners of the overlap of the top face of `below` (None: the ground) and the bottom
    face of `above`, at the height of that bottom face."""
    lo, hi = above[:2] - HALF[:2], above[:2] + HALF[:2]
    if below is not None:
        lo, hi = np.maximum(lo, below[:2] - HALF[:2]), np.minimum(hi, below[:2] + HALF[:2])
    z = above[2] - HALF[2]
    return [np.array([x, y, z]) for x in (lo[0], hi[0]) for y in (lo[1], hi[1])]


def point_jacobian(d):
    """Velocity of the point at offset d from a body's centre, in the contact frame
    (z, x, y), as a 3 x 6 block on the body's (v, omega): v + omega x d."""
    cross = np.array([[0.0, d[2], -d[1]], [-d[2], 0.0, d[0]], [d[1], -d[0], 0.0]])
    block = np.hstack([np.eye(3), cross])
    return block[[2, 0, 1]]


def contact_problem(x, v, m):
    """H (every 3 x 6 block stored, zeros included, so its pattern stays), f and w."""
    rows, cols, vals, w = [], [], [], []
    for k in range(BOXES):
        below = x[k - 1] if k > 0 else None
        gap = x[k, 2] - HALF[2] - (below[2] + HALF[2] if k > 0 else 0.0)
        for p in contact_points(below, x[k]):
            c = len(w) // 3
            for body, sign in ((k, 1.0), (k - 1, -1.0)):
                if body < 0:
                    continue
                block = sign * point_jacobian(p - x[body])
                for i in range(3):
                    for j in range(6):
                        rows.append(6 * body + j)
                        cols.append(3 * c + i)
                        vals.append(block[i, j])
            w += [gap / H_STEP, 0.0, 0.0]
    n = 6 * BOXES
    H = sp.coo_array((vals, (rows, cols)), shape=(n, len(w))).tocsc()
    f_ext = np.tile([0.0, 0.0, -MASS * GRAVITY, 0.0, 0.0, 0.0], BOXES)
    return H, m @ v + H_STEP * f_ext, np.array(w)


def simulate():
    x = np.array([[0.0, 0.0, HALF[2] * (2 * k + 1)] for k in range(BOXES)])
    v = np.zeros(6 * BOXES)
    v[6 * (BOXES - 1)] = PUSH
    m = mass_matrix()
    H, f, w = contact_problem(x, v, m)
    problem = cadmm.GlobalProblem(m, H, f, w, np.full(len(w) // 3, MU))
    solver = cadmm.Solver(problem, cadmm.Settings(tolerance=1e-8))
    errors, seconds = [], []
    for step in range(STEPS):
        if step > 0:
            H, f, w = contact_problem(x, v, m)
            solver.update_values(H=H, f=f, w=w)
            solver.warm_start(last.r, last.v)
        status = solver.solve()
        if status != cadmm.Status.SOLVED:
            raise RuntimeError(f"step {step}: {status}")
        last = solver.solution
        errors.append(cadmm.error(cadmm.GlobalProblem(m, H, f, w, problem.mu), last.r, v=last.v))
        seconds.append(solver.stats.solve_seconds)
        v = last.v
        x += H_STEP * v.reshape(BOXES, 6)[:, :3]
    return x, np.array(errors), np.array(seconds)


def plot(errors, seconds, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
    steps = np.arange(len(errors))
    top.semilogy(steps, np.maximum(errors, 1e-17), ".-")
    top.axhline(1e-8, color="gray", linestyle="--", label="tolerance")
    top.set_ylabel("error (re-measured)")
    top.legend()
    bottom.plot(steps, seconds * 1e3, ".-")
    bottom.set_ylabel("solve time (ms)")
    bottom.set_xlabel("time step (h = 1/60 s)")
    top.set_title(f"A stack of {BOXES} boxes, the top one pushed at {PUSH} m/s (cadmm, Python)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main():
    x, errors, seconds = simulate()
    slid = x[-1, 0]
    # Coulomb's sliding distance v0^2 / (2 mu g), less the half step the explicit
    # position update lags by.
    coulomb = PUSH**2 / (2 * MU * GRAVITY) - PUSH * H_STEP / 2
    print(f"{STEPS} steps, largest error {errors.max():.1e}, median solve {np.median(seconds) * 1e3:.2f} ms")
    print(f"top box slid {slid:.3f} m (Coulomb: {coulomb:.3f} m); lowest box moved {np.abs(x[0, :2]).max():.1e} m")
    if len(sys.argv) > 1:
        plot(errors, seconds, sys.argv[1])


if __name__ == "__main__":
    main()
