#!/usr/bin/env python3
"""Benchmark: cadmm `auto` next to Siconos numerics ADMM on every FCLib file, same machine,
same run, same error measure (docs/algorithms.md §3, recomputed from each solution).

usage: bench/compare_siconos.py [--tol 1e-8] [--time-limit 20] [--repeat 3] [--only PATTERN]
                                [--cadmm target/release/cadmm] [--csv OUT.csv]
Each solver runs in its own process; times are the solvers' own solve times (setup
included for cadmm: symbolic + numeric factorization), medians over --repeat runs.
Prints a table per file and, per form and overall: solved counts, median and total time,
median and total iterations, and the median per-file time ratio Siconos / cadmm.
Needs Debian's python3-siconos (run with any python3; Siconos is called via /usr/bin/python3).
"""
import argparse, glob, json, os, statistics, subprocess, sys, tempfile

# The workspace root: this file is cli/bench/<name>.py.
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SHARED = os.environ.get("CADMM_SHARED", os.path.join(ROOT, "..", "shared"))
sys.path.insert(0, os.path.join(SHARED, "tools"))


def independent_error(problem, sol):
    q = subprocess.run([sys.executable, os.path.join(SHARED, "tools", "fc_error.py"), problem, sol],
                       capture_output=True, text=True)
    try:
        return float(q.stdout.strip())
    except ValueError:
        return float("inf")


def run_cadmm(args, path):
    with tempfile.TemporaryDirectory() as d:
        sol = os.path.join(d, "s.h5")
        p = subprocess.run([args.cadmm, "solve", path, "--tol", str(args.tol), "--time-limit",
                            str(args.time_limit), "--out", sol], capture_output=True, text=True)
        if p.returncode != 0:
            return dict(status="error", seconds=None, iterations=None, error=float("inf"))
        r = json.loads(p.stdout)
        err = independent_error(path, sol)
        return dict(status="solved" if err <= args.tol else r["status"], seconds=r["seconds"],
                    iterations=r["iterations"], error=err)


def run_siconos(args, path):
    with tempfile.TemporaryDirectory() as d:
        sol = os.path.join(d, "s.h5")
        p = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "cli", "bench", "siconos_solve.py"), path,
                            "--solver", "ADMM", "--tol", str(args.tol), "--time-limit", str(args.time_limit),
                            "--out", sol], capture_output=True, text=True)
        if p.returncode != 0:
            return dict(status="error", seconds=None, iterations=None, error=float("inf"))
        r = json.loads(p.stdout)
        err = independent_error(path, sol) if os.path.exists(sol) else float("inf")
        return dict(status="solved" if err <= args.tol else r["status"], seconds=r["seconds"],
                    iterations=r["iterations"], error=err)


def median_run(fn, args, path):
    runs = [fn(args, path) for _ in range(args.repeat)]
    best = dict(runs[0])
    secs = [r["seconds"] for r in runs if r["seconds"] is not None]
    best["seconds"] = statistics.median(secs) if secs else None
    return best


def summary(name, rows, key):
    solved = [r for r in rows if r[key]["status"] == "solved"]
    t = [r[key]["seconds"] for r in solved]
    it = [r[key]["iterations"] for r in solved if r[key]["iterations"] is not None]
    if not t:
        return f"{name:8s} solved 0/{len(rows)}"
    return (f"{name:8s} solved {len(solved):2d}/{len(rows)}  time median {statistics.median(t):.4f}s "
            f"total {sum(t):8.3f}s  iterations median {statistics.median(it):7.0f} total {sum(it):9d}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tol", type=float, default=1e-8)
    ap.add_argument("--time-limit", type=float, default=20)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--only", default="")
    ap.add_argument("--cadmm", default=os.path.join(ROOT, "target", "release", "cadmm"))
    ap.add_argument("--csv")
    args = ap.parse_args()
    files = [f for f in sorted(glob.glob(os.path.join(SHARED, "data", "fclib", "*", "*.hdf5"))) if args.only in f]
    rows = []
    print(f"{'file':52s} {'cadmm':>28s} {'siconos ADMM':>28s}")
    for f in files:
        a = median_run(run_cadmm, args, f)
        b = median_run(run_siconos, args, f)
        rows.append(dict(file=os.path.relpath(f, os.path.join(SHARED, "data", "fclib")), cadmm=a, siconos=b))
        fmt = lambda r: f"{r['status'][:10]:>10s} {r['seconds'] or float('nan'):8.4f}s {r['iterations'] or 0:7d}"
        print(f"{rows[-1]['file'][:52]:52s} {fmt(a):>28s} {fmt(b):>28s}", flush=True)
    for form in ("global", "local", ""):
        sub = [r for r in rows if r["file"].startswith(form)]
        if not sub:
            continue
        print(f"\n== {form or 'all'} ({len(sub)} files, tol {args.tol:g}, limit {args.time_limit:g}s, "
              f"median of {args.repeat} runs)")
        print(summary("cadmm", sub, "cadmm"))
        print(summary("siconos", sub, "siconos"))
        both = [r for r in sub if r["cadmm"]["status"] == "solved" and r["siconos"]["status"] == "solved"]
        if both:
            ratios = [r["siconos"]["seconds"] / max(r["cadmm"]["seconds"], 1e-9) for r in both]
            print(f"median time ratio siconos/cadmm on the {len(both)} files both solve: "
                  f"{statistics.median(ratios):.1f}")
    if args.csv:
        with open(args.csv, "w") as out:
            out.write("file,solver,status,seconds,iterations,error\n")
            for r in rows:
                for k in ("cadmm", "siconos"):
                    x = r[k]
                    out.write(f"{r['file']},{k},{x['status']},{x['seconds']},{x['iterations']},{x['error']}\n")


if __name__ == "__main__":
    main()
