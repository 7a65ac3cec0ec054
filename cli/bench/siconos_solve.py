#!/usr/bin/python3
"""Solve one FCLib problem with Siconos numerics 4.4 (peer side of the cadmm benchmarks).

Run it with Debian's interpreter, the one python3-siconos is built for (NOT the pyenv
python3 that may come first on PATH):

    /usr/bin/python3 bench/siconos_solve.py PROBLEM.hdf5 --solver ADMM --tol 1e-8 \
        --time-limit 20 [--max-iter 100000] [--out SOLUTION.h5]

Needs the Debian packages python3-siconos python3-numpy python3-scipy python3-h5py.

Prints ONE line of JSON on stdout:
  {"solver": "siconos:NAME", "form": "global"|"local",
   "status": "solved"|"max_iterations"|"time_limit"|"crash"|"failed",
   "iterations": int|null, "seconds": wall time of the driver call only (for time_limit and
   crash: how long the solve ran), "siconos_error": Siconos' own final error,
   "error": the docs/algorithms.md §3 measure, null when there is no solution}
"error" is recomputed with the shared fc_error.error(); "solved" means error <= tol, whatever
Siconos says (they differ: Siconos 4.4 divides the local error by max(|q|,|u|,|r|), not |q|,
and gfc3d IPM reports its own interior-point criterion). The solve runs in a forked child that is killed at the time limit, because
some Siconos solvers abort the whole process (e.g. gfc3d IPM on Box_Stacks-i0024-549-101).
Exit code 0 whenever the script worked (even if the solver failed), 2 on bad input.
With --out, /solution/{r,u[,v]} are written (only when the solver returned a solution).

The problem is read with the shared fclib_read.py (this Debian build of Siconos has no FCLib
support), then handed to Siconos in the storage Siconos' own FCLib reader uses: sparse (CSC)
M and H for global problems, a 3x3 sparse-block (SBM) W for local ones.
"""
import argparse, json, math, multiprocessing, os, signal, sys, time

import numpy as np
import h5py

# Shared tools (fc_error.py, fclib_read.py): <project root>/../shared/tools, or $CADMM_SHARED/tools.
# The workspace root: this file is cli/bench/siconos_solve.py.
PROJECT_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SHARED = os.environ.get('CADMM_SHARED', os.path.join(PROJECT_ROOT, '..', 'shared'))
sys.path.insert(0, os.path.join(SHARED, 'tools'))
try:
    import fclib_read   # noqa: E402
    import fc_error     # noqa: E402
except ImportError as e:
    sys.exit('siconos_solve.py: error: cannot import the shared tools from %s (set '
             'CADMM_SHARED): %s' % (os.path.join(SHARED, 'tools'), e))

# Our solver names -> suffix of the Siconos solver id, per problem form.
# Global ids are SICONOS_GLOBAL_FRICTION_3D_<suffix> (gfc3d_driver),
# local ids are SICONOS_FRICTION_3D_<suffix> (fc3d_driver).
SOLVERS = {
    'global': {'ADMM': 'ADMM', 'NSGS': 'NSGS', 'NSGS_WR': 'NSGS_WR', 'IPM': 'IPM',
               'NSN_AC': 'NSN_AC', 'PROX': 'PROX_WR'},
    'local': {'ADMM': 'ADMM', 'NSGS': 'NSGS', 'NSN_AC': 'NSN_AC', 'PROX': 'PROX'},
}
PREFIX = {'global': 'SICONOS_GLOBAL_FRICTION_3D_', 'local': 'SICONOS_FRICTION_3D_'}


def die(msg):
    print('siconos_solve.py: error: ' + msg, file=sys.stderr)
    sys.exit(2)


def csc64(A):
    """CSC copy with sorted, summed entries and 64-bit indices (Siconos' CS_INT)."""
    A = A.tocsc(copy=True)
    A.sum_duplicates()
    A.indices = A.indices.astype(np.int64)
    A.indptr = A.indptr.astype(np.int64)
    return A


def build_problem(sn, d):
    """Siconos problem object from the dictionary returned by fclib_read.read()."""
    mu = np.ascontiguousarray(d['mu'], dtype=float)
    if d['kind'] == 'global':
        p = sn.GlobalFrictionContactProblem()
        p.dimension = 3
        p.numberOfContacts = len(mu)
        p.M = csc64(d['M'])          # NM_SPARSE
        p.H = csc64(d['H'])          # must be set before b (its size comes from H)
        p.q = np.ascontiguousarray(d['f'], dtype=float)   # M v = H r + q
        p.b = np.ascontiguousarray(d['w'], dtype=float)   # u = H^T v + b
        p.mu = mu
        return p
    W = csc64(d['W'])
    info, sbm = sn.SBM_from_csparse(3, W)                  # 3x3 block storage
    if info != 0:
        raise RuntimeError('SBM_from_csparse failed (%d)' % info)
    Wnm = sn.NM_new_SBM(W.shape[0], W.shape[1], sbm)
    return sn.FrictionContactProblem(3, Wnm, np.ascontiguousarray(d['q'], dtype=float), mu)


def child(conn, d, solver_id, tol, max_iter):
    """Runs in the forked process: build, solve, send the result back, exit hard."""
    # Keep stdout clean for the JSON line: some solvers (IPM) print an iteration log on
    # stdout even at verbose 0. stderr stays open for assertion/abort messages.
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    import siconos.numerics as sn
    sn.numerics_set_verbose(0)
    prob = build_problem(sn, d)
    so = sn.SolverOptions(solver_id)
    so.iparam[sn.SICONOS_IPARAM_MAX_ITER] = max_iter
    so.dparam[sn.SICONOS_DPARAM_TOL] = tol
    m = len(d['mu']) * 3
    r, u = np.zeros(m), np.zeros(m)            # zero initial guess
    v = np.zeros(d['M'].shape[0]) if d['kind'] == 'global' else None
    conn.send('started')                       # the time limit counts from here
    t0 = time.perf_counter()
    if v is not None:
        info = sn.gfc3d_driver(prob, r, u, v, so)
    else:
        info = sn.fc3d_driver(prob, r, u, so)
    seconds = time.perf_counter() - t0
    conn.send(dict(info=int(info), seconds=seconds, r=r, u=u, v=v,
                   iterations=int(so.iparam[sn.SICONOS_IPARAM_ITER_DONE]),
                   siconos_error=float(so.dparam[sn.SICONOS_DPARAM_RESIDU])))
    conn.close()
    os._exit(0)    # skip destructors (ownership of the SBM is shared with the wrapper)


def run(d, solver_id, tol, max_iter, time_limit):
    """Returns (status, result, seconds): status None when the child sent a result back;
    otherwise 'time_limit' or 'crash' with the wall seconds the solve had been running."""
    ctx = multiprocessing.get_context('fork')
    parent_conn, child_conn = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=child, args=(child_conn, d, solver_id, tol, max_iter))
    proc.start()
    child_conn.close()
    t0 = None
    try:
        # Building the Siconos problem is not part of the limit; allow it generously.
        if not parent_conn.poll(max(60.0, time_limit)) or parent_conn.recv() != 'started':
            raise EOFError
        t0 = time.perf_counter()
        if not parent_conn.poll(time_limit):
            proc.join(0.1)              # did it just die (abort right at the limit)?
            if proc.exitcode is not None:
                raise EOFError
            proc.kill()
            proc.join()
            return 'time_limit', None, time.perf_counter() - t0
        res = parent_conn.recv()
    except (EOFError, OSError):
        # The child died before sending (abort/assert/segfault) or never got started.
        seconds = None if t0 is None else time.perf_counter() - t0
        if proc.is_alive():
            proc.kill()
        proc.join()
        code = proc.exitcode
        how = ('signal %s' % signal.Signals(-code).name) if code is not None and code < 0 \
            else 'exit code %s' % code
        print('siconos_solve.py: solver process died (%s)%s' % (
            how, '' if t0 is not None else ' before the solve started'), file=sys.stderr)
        return 'crash', None, seconds
    proc.join()
    return None, res, res['seconds']


def finite_or_none(x):
    return float(x) if x is not None and math.isfinite(x) else None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('problem')
    ap.add_argument('--solver', required=True,
                    help='one of ADMM, NSGS, NSGS_WR, IPM, NSN_AC, PROX')
    ap.add_argument('--tol', type=float, default=1e-8)
    ap.add_argument('--time-limit', type=float, default=20.0)
    ap.add_argument('--max-iter', type=int, default=100000)
    ap.add_argument('--out', help='write /solution/{r,u,v} here (HDF5)')
    a = ap.parse_args()

    name = a.solver.upper()
    if not any(name in s for s in SOLVERS.values()):
        die('unknown solver %r (choose from ADMM, NSGS, NSGS_WR, IPM, NSN_AC, PROX)' % a.solver)
    try:
        d = fclib_read.read(a.problem)
    except Exception as e:
        die('cannot read FCLib problem %r: %s' % (a.problem, e))
    form = d['kind']
    if name not in SOLVERS[form]:
        die('solver %s is not available for %s problems (choose from %s)'
            % (name, form, ', '.join(SOLVERS[form])))
    try:
        import siconos.numerics as sn
    except ImportError as e:
        die('cannot import siconos.numerics (%s); run with /usr/bin/python3 and install '
            'python3-siconos' % e)
    solver_id = getattr(sn, PREFIX[form] + SOLVERS[form][name])
    if a.out and os.path.exists(a.out):
        os.remove(a.out)       # never leave a stale solution behind a time_limit/crash

    status, res, seconds = run(d, solver_id, a.tol, a.max_iter, a.time_limit)
    out = {'solver': 'siconos:' + name, 'form': form, 'status': status, 'iterations': None,
           'seconds': seconds, 'siconos_error': None, 'error': None}
    if res is not None:
        err = fc_error.error(d, res['r'], res['v'])      # the common measure, recomputed
        if err <= a.tol:
            status = 'solved'
        elif res['iterations'] >= a.max_iter:
            status = 'max_iterations'
        else:
            status = 'failed'
        out.update(status=status, iterations=res['iterations'],
                   siconos_error=finite_or_none(res['siconos_error']),
                   error=finite_or_none(err))
        if a.out:
            with h5py.File(a.out, 'w') as h:
                g = h.create_group('solution')
                for k in ('r', 'u', 'v'):
                    if res[k] is not None:
                        g.create_dataset(k, data=np.asarray(res[k], dtype=np.float64))
    print(json.dumps(out))
    sys.stdout.flush()


if __name__ == '__main__':
    main()
