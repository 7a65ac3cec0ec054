#!/usr/bin/python3
"""Scale benchmark: time and peak memory against contact count, cadmm configurations next to
Siconos solvers in one run, on piles written by `examples/scale.rs`.

    cargo run --release --features fclib --example scale -- --dump target/scale-piles
    cargo build --release -p cadmm-cli --all-features
    /usr/bin/python3 cli/bench/scale.py target/scale-piles/*.hdf5 \
        [--tol 1e-4,1e-8] [--time-limit 120] [--repeat 3] [--configs auto,admm,...]
        [--siconos NSGS_WR,ADMM] [--out target/scale.jsonl] [--plot docs/perf/scale.png]
    /usr/bin/python3 cli/bench/scale.py --replot target/scale.jsonl --plot docs/perf/scale.png

Run it with Debian's /usr/bin/python3 (numpy, scipy, h5py, matplotlib; python3-siconos for
the Siconos side, called as $CADMM_PYTHON or /usr/bin/python3 through siconos_solve.py).

For each file, tolerance and repetition, every solver runs once, in turn, each in its own
process (so the repetitions of one solver are spread over the run, not back to back):
- cadmm configurations: `cadmm solve` with the extra flags of CADMM_CONFIGS; a
  configuration whose flags this binary does not know is skipped with a note;
- Siconos solvers: `siconos_solve.py --solver NAME` (global form, zero initial guess, the
  solver's defaults), which kills the solve at the time limit.
Per run: the solver's own time ("seconds": setup and solve for cadmm, the driver call for
Siconos), the process's wall time, iterations, status, the error recomputed from the
solution with the shared fc_error.py at full precision ("solved" means that error <= tol),
and the peak resident memory of the process and the processes it waited for (wait4's
ru_maxrss; for Siconos this includes the Python driver holding the problem). One JSON line
per file, tolerance and solver with the median over the repetitions (the run of median
time gives status, iterations and error; memory is the median peak), and the runs
themselves. The plot: time and peak memory against contacts, log-log, one line per
solver and tolerance, one column per pile kind; hollow markers did not reach tol.
"""
import argparse, json, os, re, statistics, subprocess, sys, tempfile, threading, time

import numpy as np
import h5py

# The workspace root: this file is cli/bench/scale.py.
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SHARED = os.environ.get("CADMM_SHARED", os.path.join(ROOT, "..", "shared"))
sys.path.insert(0, os.path.join(SHARED, "tools"))
import fclib_read  # noqa: E402
import fc_error  # noqa: E402

# cadmm configurations: name -> extra `cadmm solve` flags. Add a row to compare another.
CADMM_CONFIGS = {
    "auto": [],
    "admm": ["--newton", "off"],               # ADMM alone, no Newton phase
    "direct": ["--linear-solver", "direct"],
    "iterative": ["--linear-solver", "iterative"],
    "auto-2t": ["--threads", "2"],             # a problem solved whole: threaded products
}
# Siconos solvers of siconos_solve.py for global problems.
SICONOS_DEFAULT = "NSGS_WR,ADMM"


def wait_rusage(proc, limit):
    """Waits for `proc` (killing its process group after `limit` seconds); returns
    (exit code, killed, peak RSS in MB of it and the children it waited for)."""
    killed = []

    def kill():
        killed.append(True)
        try:
            os.killpg(proc.pid, 9)
        except ProcessLookupError:
            pass

    timer = threading.Timer(limit, kill)
    timer.start()
    try:
        # wait4 rather than Popen.wait: the rusage of this one child, not the cumulative
        # maximum over every child that RUSAGE_CHILDREN gives.
        _, status, ru = os.wait4(proc.pid, 0)
    finally:
        timer.cancel()
    proc.returncode = os.waitstatus_to_exitcode(status)
    return proc.returncode, bool(killed), ru.ru_maxrss / 1024.0


def spawn(cmd, limit):
    """Runs `cmd` in its own process group; returns (code, killed, stdout, stderr, wall,
    peak MB)."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, start_new_session=True)
        code, killed, peak = wait_rusage(proc, limit)
        wall = time.perf_counter() - t0
        out.seek(0)
        err.seek(0)
        return code, killed, out.read(), err.read(), wall, peak


def independent_error(d, sol):
    try:
        with h5py.File(sol, "r") as h:
            s = h["solution"]
            r = np.array(s["r"])
            v = np.array(s["v"]) if "v" in s else None
    except (OSError, KeyError):
        return None
    e = fc_error.error(d, r, v)
    return e if np.isfinite(e) else None


def run_cadmm(args, path, d, tol, extra):
    with tempfile.TemporaryDirectory() as tmp:
        sol = os.path.join(tmp, "s.h5")
        cmd = [args.cadmm, "solve", path, "--tol", repr(tol), "--time-limit", repr(args.time_limit),
               "--max-iter", str(args.max_iter), "--out", sol] + extra
        code, killed, out, err, wall, peak = spawn(cmd, args.outer_limit)
        run = dict(status=None, seconds=None, wall=wall, iterations=None, error=None, peak_mb=peak)
        if killed:
            run["status"] = "killed"
            return run
        if code != 0:
            run["status"] = "error: " + (err.strip().splitlines() or ["exit code %d" % code])[-1]
            return run
        r = json.loads(out)
        run.update(seconds=r["seconds"], iterations=r["iterations"],
                   error=independent_error(d, sol))
        ok = run["error"] is not None and run["error"] <= tol
        # "solved" only by the independent measure.
        run["status"] = "solved" if ok else ("unconfirmed" if r["status"] == "solved" else r["status"])
        return run


def run_siconos(args, path, d, tol, name):
    cmd = [args.python, os.path.join(ROOT, "cli", "bench", "siconos_solve.py"), path, "--solver", name,
           "--tol", repr(tol), "--time-limit", repr(args.time_limit), "--max-iter", str(args.max_iter)]
    code, killed, out, err, wall, peak = spawn(cmd, args.outer_limit)
    run = dict(status=None, seconds=None, wall=wall, iterations=None, error=None, peak_mb=peak)
    if killed:
        run["status"] = "killed"
    elif code != 0 or not out.strip():
        run["status"] = "error: " + (err.strip().splitlines() or ["exit code %d" % code])[-1]
    else:
        # siconos_solve.py re-measures with fc_error.error itself (full precision in JSON).
        r = json.loads(out.strip().splitlines()[-1])
        run.update(status=r["status"], seconds=r["seconds"], iterations=r["iterations"], error=r["error"])
    return run


def summarize(runs):
    """The median over repetitions: time of all runs (None counts as infinite), the fields
    of the median-time run, the median peak memory."""
    key = lambda r: r["seconds"] if r["seconds"] is not None else float("inf")
    mid = sorted(runs, key=key)[(len(runs) - 1) // 2]
    secs = sorted(key(r) for r in runs)
    med = statistics.median(secs)
    return dict(status=mid["status"], seconds=med if med != float("inf") else None,
                wall=statistics.median(r["wall"] for r in runs), iterations=mid["iterations"],
                error=mid["error"], peak_mb=statistics.median(r["peak_mb"] for r in runs))


def pile_kind(path):
    m = re.match(r"(.*)-pile-\d+\.hdf5$", os.path.basename(path))
    return m.group(1) if m else "other"


def cadmm_flags(cadmm):
    """The long flags `cadmm solve --help` lists."""
    p = subprocess.run([cadmm, "solve", "--help"], capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit("scale.py: %s solve --help failed: %s" % (cadmm, p.stderr.strip()))
    return set(re.findall(r"--[a-z][a-z0-9-]*", p.stdout))


def baseline_mb(cmd):
    """Peak memory of the driver alone (what every run of it carries besides the solve)."""
    try:
        return spawn(cmd, 60)[5]
    except OSError:
        return None


def plot(rows, path, time_limit=None):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("scale.py: matplotlib is not importable; no plot written", file=sys.stderr)
        return
    kinds = sorted({r["pile"] for r in rows})
    solvers = list(dict.fromkeys(r["solver"] for r in rows))
    tols = sorted({r["tol"] for r in rows}, reverse=True)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    styles = ["-", "--", ":", "-."]
    fig, axes = plt.subplots(2, len(kinds), figsize=(6 * len(kinds), 8), squeeze=False)
    for c, kind in enumerate(kinds):
        for si, solver in enumerate(solvers):
            for ti, tol in enumerate(tols):
                pts = sorted((r["contacts"], r) for r in rows
                             if r["pile"] == kind and r["solver"] == solver and r["tol"] == tol)
                if not pts:
                    continue
                color, style = colors[si % len(colors)], styles[ti % len(styles)]
                label = "%s %g" % (solver, tol)
                for row, field in ((0, "seconds"), (1, "peak_mb")):
                    ax = axes[row][c]
                    xy = [(n, r[field]) for n, r in pts if r[field] is not None]
                    if not xy:
                        continue
                    ax.plot([p[0] for p in xy], [p[1] for p in xy], style, color=color, label=label)
                    solved = [(n, r[field]) for n, r in pts if r[field] is not None and r["status"] == "solved"]
                    other = [(n, r[field]) for n, r in pts if r[field] is not None and r["status"] != "solved"]
                    if solved:
                        ax.plot(*zip(*solved), "o", color=color)
                    if other:
                        ax.plot(*zip(*other), "o", color=color, markerfacecolor="none")
        for row, what in ((0, "solver time (s)"), (1, "peak memory (MB)")):
            ax = axes[row][c]
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel("contacts")
            ax.set_ylabel(what)
            ax.set_title("%s pile" % kind)
            ax.grid(True, which="both", alpha=0.3)
            if row == 0 and time_limit:
                ax.axhline(time_limit, color="gray", lw=0.8)
        axes[0][c].legend(fontsize=7)
    fig.suptitle("Scale: hollow markers did not reach tol%s" % (
        " (grey line: time limit)" if time_limit else ""))
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    print("plot: %s" % path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("files", nargs="*", help="FCLib global problems (lattice-pile-N.hdf5, ...)")
    ap.add_argument("--tol", default="1e-4,1e-8")
    ap.add_argument("--time-limit", type=float, default=120.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--max-iter", type=int, default=10_000_000)
    ap.add_argument("--configs", default=",".join(CADMM_CONFIGS),
                    help="cadmm configurations (of: %s); empty for none" % ", ".join(CADMM_CONFIGS))
    ap.add_argument("--siconos", default=SICONOS_DEFAULT,
                    help="siconos_solve.py solvers (NSGS_WR, ADMM, NSGS, NSN_AC, IPM, PROX); empty for none")
    ap.add_argument("--cadmm", default=os.path.join(ROOT, "target", "release", "cadmm"))
    ap.add_argument("--python", default=os.environ.get("CADMM_PYTHON", "/usr/bin/python3"),
                    help="Python with python3-siconos")
    ap.add_argument("--out", default=os.path.join(ROOT, "target", "scale.jsonl"))
    ap.add_argument("--plot", default=os.path.join(ROOT, "docs", "perf", "scale.png"))
    ap.add_argument("--replot", metavar="JSONL", help="only plot the results of an earlier run")
    args = ap.parse_args()

    if args.replot:
        with open(args.replot) as f:
            rows = [json.loads(line) for line in f if line.strip()]
        plot(rows, args.plot, rows[0].get("time_limit") if rows else None)
        return
    if not args.files:
        ap.error("no problem files (write them with the scale example's --dump)")
    tols = [float(t) for t in args.tol.split(",") if t]
    # cadmm's time limit is checked between iterations and its setup is not bounded, so the
    # process itself gets a generous limit of its own.
    args.outer_limit = 2 * args.time_limit + 60

    solvers = []
    known = cadmm_flags(args.cadmm) if args.configs else set()
    for name in [c for c in args.configs.split(",") if c]:
        if name not in CADMM_CONFIGS:
            ap.error("unknown cadmm configuration %r (of: %s)" % (name, ", ".join(CADMM_CONFIGS)))
        extra = CADMM_CONFIGS[name]
        missing = [a for a in extra if a.startswith("--") and a not in known]
        if missing:
            print("note: cadmm:%s skipped: %s does not take %s" % (name, args.cadmm, " ".join(missing)))
            continue
        solvers.append(("cadmm:" + name, extra, lambda path, d, tol, extra=extra: run_cadmm(args, path, d, tol, extra)))
    for name in [s.upper() for s in args.siconos.split(",") if s]:
        solvers.append(("siconos:" + name, [name], lambda path, d, tol, name=name: run_siconos(args, path, d, tol, name)))
    if not solvers:
        ap.error("no solver to run")

    base = {}
    if args.configs:
        base["cadmm"] = baseline_mb([args.cadmm, "--version"])
    if args.siconos:
        base["siconos"] = baseline_mb([args.python, "-c", "import numpy, scipy.sparse, h5py, siconos.numerics"])
    print("driver baselines (peak MB of the driver doing nothing): %s" % ", ".join(
        "%s %.0f" % (k, v) for k, v in base.items() if v is not None))

    rows = []
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w") as out:
        print("%-28s %6s %-18s %-13s %10s %9s %10s %9s %9s" % (
            "file", "tol", "solver", "status", "seconds", "wall", "iterations", "error", "peak MB"))
        for path in args.files:
            d = fclib_read.read(path)
            if d["kind"] != "global":
                print("note: %s skipped: not a global problem" % path)
                continue
            info = dict(file=os.path.basename(path), pile=pile_kind(path), contacts=len(d["mu"]),
                        n=d["M"].shape[0], nnz_h=int(d["H"].nnz))
            for tol in tols:
                runs = {s[0]: [] for s in solvers}
                for _ in range(args.repeat):
                    for name, _, fn in solvers:
                        runs[name].append(fn(path, d, tol))
                for name, extra, _ in solvers:
                    m = summarize(runs[name])
                    row = dict(info, tol=tol, solver=name, args=extra, time_limit=args.time_limit,
                               repeat=args.repeat, baseline_mb=base.get(name.split(":")[0]), **m,
                               runs=runs[name])
                    rows.append(row)
                    out.write(json.dumps(row) + "\n")
                    out.flush()
                    f = lambda x, fmt: (fmt % x) if x is not None else "-"
                    print("%-28s %6g %-18s %-13s %10s %9.3f %10s %9s %9.0f" % (
                        info["file"][:28], tol, name, m["status"][:13], f(m["seconds"], "%.4f"), m["wall"],
                        f(m["iterations"], "%d"), f(m["error"], "%.2e"), m["peak_mb"]), flush=True)
    print("results: %s" % args.out)
    plot(rows, args.plot, args.time_limit)


if __name__ == "__main__":
    main()
