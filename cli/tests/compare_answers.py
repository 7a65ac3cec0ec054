#!/usr/bin/python3
"""Measures two answers to the same FCLib problem (test helper of siconos_compare.rs).

usage: compare_answers.py TOOLS_DIR PROBLEM ANSWER_A ANSWER_B [PROBLEM ANSWER_A ANSWER_B ...]
ANSWER_B may be '-' (no second answer). Prints one JSON line per problem with
  e_a, e_b          the shared fc_error.error() of each answer (full precision)
  sigma_max, sigma_min, asym
                    singular values of the Delassus matrix W (H^T M^-1 H for a global
                    problem) and max|W - W^T| / max|W|
  scale_a, scale_b  S such that an answer with error <= tol has a natural-map residual of
                    the reduced problem u = W r + q below tol * S (see below)
  r_a, r_b, dr      ||r_a||, ||r_b||, ||r_a - r_b||
  u_a, u_b, du      the same for u = W r + q
The reduced problem: local, (W, q) as stored; global, W = H^T M^-1 H and q = H^T M^-1 f + w,
so that both forms compare r and u the same way. Local: the measure divides the natural map
by ||q||, so S = ||q||. Global: the measure bounds the equation residual rho = -Mv + Hr + f
by tol * max(||f||, ||Mv||, ||Hr||) and the natural map at the answer's own u = H^T v + w by
tol * max(||u||, ||r||); that u differs from W r + q by H^T M^-1 rho, and the natural map is
(1 + mu_max)-Lipschitz in u, so S = max(||u||, ||r||) + (1 + mu_max) ||H^T M^-1|| max(...).
Dense linear algebra: only meant for small problems.
"""
import json, sys
import numpy as np
import h5py

sys.path.insert(0, sys.argv[1])
import fclib_read   # noqa: E402
import fc_error     # noqa: E402


def answer(path):
    s = h5py.File(path, 'r')['solution']
    return np.array(s['r']), (np.array(s['v']) if 'v' in s else None)


def main():
    args = sys.argv[2:]
    if len(args) % 3 != 0 or not args:
        sys.exit('usage: compare_answers.py TOOLS_DIR (PROBLEM ANSWER_A ANSWER_B|-)...')
    for k in range(0, len(args), 3):
        problem, path_a, path_b = args[k:k + 3]
        d = fclib_read.read(problem)
        mu_max = float(np.max(d['mu'])) if len(d['mu']) else 0.0
        if d['kind'] == 'global':
            M, H = d['M'].toarray(), d['H'].toarray()
            HtMi = np.linalg.solve(M.T, H).T          # H^T M^-1
            W = HtMi @ H
            q = HtMi @ d['f'] + d['w']
            norm_HtMi = np.linalg.norm(HtMi, 2)
        else:
            W, q = d['W'].toarray(), d['q']

        def scale(r, v):
            if d['kind'] == 'local':
                return float(np.linalg.norm(q))
            Mv, Hr = d['M'] @ v, d['H'] @ r
            u = d['H'].T @ v + d['w']
            s1 = max(np.linalg.norm(d['f']), np.linalg.norm(Mv), np.linalg.norm(Hr))
            s2 = max(np.linalg.norm(u), np.linalg.norm(r))
            return float(s2 + (1.0 + mu_max) * norm_HtMi * s1)

        sv = np.linalg.svd(W, compute_uv=False)
        wmax = np.max(np.abs(W)) if W.size else 0.0
        out = dict(problem=problem, sigma_max=float(sv[0]), sigma_min=float(sv[-1]),
                   asym=float(np.max(np.abs(W - W.T)) / wmax) if wmax > 0 else 0.0)
        ra, va = answer(path_a)
        ua = W @ ra + q
        out.update(e_a=float(fc_error.error(d, ra, va)), scale_a=scale(ra, va),
                   r_a=float(np.linalg.norm(ra)), u_a=float(np.linalg.norm(ua)))
        if path_b != '-':
            rb, vb = answer(path_b)
            ub = W @ rb + q
            out.update(e_b=float(fc_error.error(d, rb, vb)), scale_b=scale(rb, vb),
                       r_b=float(np.linalg.norm(rb)), u_b=float(np.linalg.norm(ub)),
                       dr=float(np.linalg.norm(ra - rb)), du=float(np.linalg.norm(ua - ub)))
        # Infinity (an answer with a non-finite entry) is written as null.
        print(json.dumps({k: (v if not isinstance(v, float) or np.isfinite(v) else None)
                          for k, v in out.items()}))
        sys.stdout.flush()


if __name__ == '__main__':
    main()
