#!/usr/bin/env python3
"""Solve every FCLib file with `cadmm solve` and re-measure each solution independently.

usage: bench/sweep.py [--cadmm target/release/cadmm] [--tol 1e-8] [--time-limit 30]
                      [--jobs 2] [--only PATTERN] [-- extra cadmm solve flags]
Prints one line per file (status, iterations, seconds, cadmm error, fc_error.py error)
and a summary; exit code 1 when a file is not solved at tol by the independent measure.
"""
import argparse, concurrent.futures as cf, glob, json, os, subprocess, sys, tempfile

# The workspace root: this file is cli/bench/<name>.py.
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SHARED = os.environ.get("CADMM_SHARED", os.path.join(ROOT, "..", "shared"))


def run(path, args, extra):
    with tempfile.TemporaryDirectory() as d:
        sol = os.path.join(d, "sol.h5")
        cmd = [args.cadmm, "solve", path, "--tol", str(args.tol), "--time-limit", str(args.time_limit),
               "--out", sol] + extra
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=args.time_limit + 120)
        if p.returncode != 0:
            return path, None, p.stderr.strip()
        res = json.loads(p.stdout)
        q = subprocess.run([sys.executable, os.path.join(SHARED, "tools", "fc_error.py"), path, sol],
                           capture_output=True, text=True)
        res["independent_error"] = float(q.stdout.strip()) if q.returncode == 0 else float("inf")
        return path, res, None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cadmm", default=os.path.join(ROOT, "target", "release", "cadmm"))
    ap.add_argument("--tol", type=float, default=1e-8)
    ap.add_argument("--time-limit", type=float, default=30)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--only", default="")
    ap.add_argument("extra", nargs="*")
    args = ap.parse_args()
    files = sorted(glob.glob(os.path.join(SHARED, "data", "fclib", "*", "*.hdf5")))
    files = [f for f in files if args.only in f]
    failures, rows = 0, []
    with cf.ThreadPoolExecutor(args.jobs) as ex:
        for path, res, err in ex.map(lambda f: run(f, args, args.extra), files):
            name = os.path.relpath(path, os.path.join(SHARED, "data", "fclib"))
            if res is None:
                failures += 1
                print(f"{name:55s} ERROR {err}", flush=True)
                continue
            ok = res["independent_error"] <= args.tol
            failures += not ok
            rows.append(res)
            print(f"{name:55s} {res['status']:15s} it={res['iterations']:7d} t={res['seconds'] or 0:9.4f}s "
                  f"err={res['error'] or float('inf'):.2e} indep={res['independent_error']:.2e} "
                  f"{'' if ok else 'FAIL'}", flush=True)
    its = sorted(r["iterations"] for r in rows)
    ts = sorted(r["seconds"] or 0 for r in rows)
    if rows:
        print(f"solved {len(files) - failures}/{len(files)}; median iterations {its[len(its)//2]}, "
              f"median seconds {ts[len(ts)//2]:.4f}, total seconds {sum(ts):.2f}")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
