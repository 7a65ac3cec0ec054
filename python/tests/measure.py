"""An independent numpy copy of the error measure every cadmm test uses.

global: e = ||-M v + H r + f|| / max(||f||, ||M v||, ||H r||)
          + ||r - P_K(r - (u + Phi(u)))|| / max(||u||, ||r||),   u = H^T v + w
local:  e = ||r - P_K(r - (u + Phi(u)))|| / ||q||,                u = W r + q

with Phi(u) = (mu ||u_T||, 0, 0) per contact (normal first) and each denominator skipped
below 1.5e-8.
"""

import numpy as np

import cadmm

FLOOR = 1.5e-8


def project_cone(z: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """Projection of each row of ``z`` (n, t1, t2) onto the cone ||t|| <= mu n."""
    n, t = z[:, 0], z[:, 1:]
    nt = np.linalg.norm(t, axis=1)
    out = z.copy()
    to_zero = mu * nt + n <= 0  # in the polar cone (tested first: mu = 0 needs it)
    onto_surface = ~to_zero & (nt > mu * n)
    a = (n + mu * nt) / (1 + mu * mu)
    safe_nt = np.where(nt > 0, nt, 1.0)
    out[onto_surface, 0] = a[onto_surface]
    out[onto_surface, 1:] = (t * (mu * a / safe_nt)[:, None])[onto_surface]
    out[to_zero] = 0.0
    return out


def natural_map_residual(r, u, mu) -> float:
    r3, u3 = r.reshape(-1, 3), u.reshape(-1, 3).copy()
    u3[:, 0] += mu * np.linalg.norm(u3[:, 1:], axis=1)
    return float(np.linalg.norm(r3 - project_cone(r3 - u3, mu)))


def _relative(x: float, scale: float) -> float:
    return x / scale if scale > FLOOR else x


def error(problem, r, v=None) -> float:
    """The measure of ``(r, v)`` on a problem without joints."""
    r = np.asarray(r, dtype=float)
    if not np.all(np.isfinite(r)) or (v is not None and not np.all(np.isfinite(v))):
        return float("inf")
    mu = problem.mu
    if isinstance(problem, cadmm.LocalProblem):
        u = problem.W @ r + problem.q
        return natural_map_residual(r, u, mu) / max(np.linalg.norm(problem.q), 1e-300)
    assert problem.n_joints == 0, "the measure here covers problems without joints"
    M, H, f = problem.M, problem.H, problem.f
    Mv, Hr = M @ v, H @ r
    equation = _relative(
        np.linalg.norm(-Mv + Hr + f), max(np.linalg.norm(f), np.linalg.norm(Mv), np.linalg.norm(Hr))
    )
    u = H.T @ v + problem.w
    contact = _relative(natural_map_residual(r, u, mu), max(np.linalg.norm(u), np.linalg.norm(r)))
    return equation + contact
