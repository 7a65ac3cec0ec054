#!/usr/bin/python3
"""Scaling of the distributed solve (feature mpi): strong scaling (one pile on 1, 2, 4
processes) and weak scaling (the pile grows with the processes, contacts per process fixed),
with the one-process solver (`cadmm solve`, default settings) on the same strong pile side
by side. The distributed runs switch islands off, so that one process runs the distributed
solve as well: the strong series is the distributed solve's own scaling.

    cargo build --release --features mpi --example distributed
    cargo build --release -p cadmm-cli --all-features
    cargo run --release --features fclib --example scale -- --dump target/dist --sizes 26x26x51
    /usr/bin/python3 cli/bench/distributed_scale.py [--kind lattice] [--strong 26x26x51]
        [--weak 13x26x51] [--np 1,2,4] [--tol 1e-4] [--repeat 3]
        [--one-process target/dist/lattice-pile-100776.hdf5] [--big 55x55x112 --big-np 4]
        [--out target/distributed.jsonl] [--plot docs/perf/distributed.png]

Each configuration runs `mpirun --oversubscribe -np K examples/distributed`, once with
`--check` (the answer gathered and measured on the whole pile by the independent measure of
tests/common; not timed) and `--repeat` times timed, the repetitions interleaved over the
configurations. Per run: the solve time (the slowest process), each process's time in
exchanges with the others (waiting included) and the rest as its own work, time per
iteration, peak memory per process. Medians over the repetitions. On a machine with C
cores, runs on more than C processes are oversubscribed: only correctness and memory mean
anything there, and the plot marks them.
"""
import argparse, json, os, statistics, subprocess, sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
EXAMPLE = os.path.join(ROOT, "target", "release", "examples", "distributed")
CLI = os.path.join(ROOT, "target", "release", "cadmm")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")


def dims(text):
    x, y, z = (int(v) for v in text.split("x"))
    return x, y, z


def run(kind, d, np, tol, check, time_limit=None):
    # Islands off: one process runs the distributed solve too (with islands on it would
    # solve a one-island pile by the one-process solver, which runs side by side below).
    cmd = ["mpirun", "--oversubscribe", "-np", str(np), EXAMPLE, "--kind", kind,
           "--dims", "%dx%dx%d" % d, "--tol", str(tol), "--islands", "off"] + (
               ["--check"] if check else []) + (
               ["--time-limit", str(time_limit)] if time_limit else [])
    out = subprocess.run(cmd, capture_output=True, text=True, env=ENV, timeout=3600)
    if out.returncode != 0:
        sys.exit("distributed_scale: %s failed:\n%s\n%s" % (" ".join(cmd), out.stdout, out.stderr))
    ranks = [json.loads(l) for l in out.stdout.splitlines() if l.startswith("{")]
    assert len(ranks) == np, out.stdout
    ranks.sort(key=lambda r: r["rank"])
    solve = max(r["solve_seconds"] for r in ranks)
    exchange = statistics.mean(r["exchange_seconds"] for r in ranks)
    return {
        "kind": kind, "dims": "%dx%dx%d" % d, "processes": np,
        "contacts": ranks[0]["contacts"], "status": ranks[0]["status"],
        "iterations": ranks[0]["iterations"], "linear_iterations": ranks[0]["linear_iterations"],
        "error": ranks[0]["error"], "checked_error": ranks[0]["checked_error"],
        "solve_seconds": solve, "setup_seconds": max(r["setup_seconds"] for r in ranks),
        "exchange_seconds": exchange, "compute_seconds": solve - exchange,
        "per_iteration_ms": 1e3 * solve / max(ranks[0]["iterations"], 1),
        "peak_mb_per_process": max(r["peak_mb"] for r in ranks),
        "owned_contacts": [r["owned_contacts"] for r in ranks],
    }


def one_process(path, tol):
    cmd = [CLI, "solve", "--tol", str(tol), "--json", path]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=3600)
    if out.returncode != 0:
        sys.exit("distributed_scale: %s failed: %s" % (" ".join(cmd), out.stderr))
    j = json.loads(out.stdout.strip().splitlines()[-1])
    return {"seconds": j["seconds"], "iterations": j["iterations"], "status": j["status"],
            "error": j["error"]}


def median_of(runs):
    keep = dict(runs[0])
    for key in ("solve_seconds", "setup_seconds", "exchange_seconds", "compute_seconds",
                "per_iteration_ms", "peak_mb_per_process"):
        keep[key] = statistics.median(r[key] for r in runs)
    keep["runs"] = [r["solve_seconds"] for r in runs]
    return keep


def plot(rows, path, cores):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    for ax, series, title in ((axes[0], "strong", "strong scaling"),
                              (axes[1], "weak", "weak scaling")):
        rs = sorted((r for r in rows if r.get("series") == series), key=lambda r: r["processes"])
        if not rs:
            continue
        np_ = [r["processes"] for r in rs]
        compute = [r["compute_seconds"] for r in rs]
        exchange = [r["exchange_seconds"] for r in rs]
        ax.bar(np_, compute, label="own work (mean over processes)", color="tab:blue")
        ax.bar(np_, exchange, bottom=compute, label="exchanges, waiting included", color="tab:orange")
        for r in rs:
            if r["processes"] > cores:
                ax.annotate("oversubscribed", (r["processes"], r["solve_seconds"]),
                            ha="center", va="bottom", fontsize=8)
        ax.set_xticks(np_)
        ax.set_xlabel("MPI processes (%d cores)" % cores)
        ax.set_ylabel("solve seconds (slowest process)")
        ax.set_title("%s: %s, %s contacts%s" % (
            title, rs[0]["kind"], "/".join(str(r["contacts"]) for r in rs) if series == "weak"
            else rs[0]["contacts"], ", tol %g" % rs[0]["tol"]))
        if series == "strong" and rs[0].get("one_process"):
            ax.axhline(rs[0]["one_process"]["seconds"], color="k", ls="--",
                       label="one-process solver")
        ax.legend(fontsize=8)
    ax = axes[2]
    for series, marker in (("strong", "o"), ("weak", "s"), ("big", "^")):
        rs = sorted((r for r in rows if r.get("series") == series), key=lambda r: r["processes"])
        if rs:
            ax.plot([r["processes"] for r in rs], [r["peak_mb_per_process"] for r in rs],
                    marker=marker, label="%s (%s contacts)" % (series, rs[-1]["contacts"]))
    ax.set_xlabel("MPI processes")
    ax.set_ylabel("peak memory per process (MB)")
    ax.set_yscale("log")
    ax.set_title("memory per process")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print("distributed_scale: wrote", path)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--kind", default="lattice")
    ap.add_argument("--strong", type=dims, default=(26, 26, 51))
    ap.add_argument("--weak", type=dims, default=(13, 26, 51), help="the pile of one process")
    ap.add_argument("--np", default="1,2,4")
    ap.add_argument("--tol", type=float, default=1e-4)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--one-process", help="FCLib file of the strong pile (examples/scale.rs)")
    ap.add_argument("--big", type=dims, help="one large pile, run once with --check")
    ap.add_argument("--big-np", type=int, default=4)
    ap.add_argument("--big-time-limit", type=float, default=900.0)
    ap.add_argument("--out", default=os.path.join(ROOT, "target", "distributed.jsonl"))
    ap.add_argument("--plot")
    ap.add_argument("--replot", help="plot the rows of this JSONL file only")
    a = ap.parse_args()
    cores = os.cpu_count() or 1
    if a.replot:
        with open(a.replot) as f:
            plot([json.loads(l) for l in f], a.plot, cores)
        return
    nps = [int(v) for v in a.np.split(",")]
    configs = [("strong", a.strong, k) for k in nps]
    configs += [("weak", (a.weak[0] * k, a.weak[1], a.weak[2]), k) for k in nps]
    runs = {c: [] for c in configs}
    checks = {}
    for c in configs:
        checks[c] = run(a.kind, c[1], c[2], a.tol, True)
        print("check", c, checks[c]["status"], checks[c]["checked_error"], flush=True)
    peer = []
    for rep in range(a.repeat):
        for c in configs:
            runs[c].append(run(a.kind, c[1], c[2], a.tol, False))
            print("run", rep, c, "%.2f s" % runs[c][-1]["solve_seconds"], flush=True)
        if a.one_process:
            peer.append(one_process(a.one_process, a.tol))
            print("run", rep, "one process", "%.2f s" % peer[-1]["seconds"], flush=True)
    rows = []
    for c in configs:
        row = median_of(runs[c])
        row.update(series=c[0], tol=a.tol, checked_error=checks[c]["checked_error"],
                   check_status=checks[c]["status"])
        if c[0] == "strong" and peer:
            row["one_process"] = dict(peer[0], seconds=statistics.median(p["seconds"] for p in peer),
                                      runs=[p["seconds"] for p in peer])
        rows.append(row)
    base = {s: next(r for r in rows if r["series"] == s and r["processes"] == nps[0])
            for s in ("strong", "weak")}
    for r in rows:
        b = base[r["series"]]
        r["speedup"] = b["solve_seconds"] / r["solve_seconds"]
        r["per_iteration_speedup"] = b["per_iteration_ms"] / r["per_iteration_ms"]
    if a.big:
        big = run(a.kind, a.big, a.big_np, a.tol, True, a.big_time_limit)
        big.update(series="big", tol=a.tol)
        rows.append(big)
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    with open(a.out, "w") as f:
        for r in rows:
            f.write(json.dumps(r) + "\n")
    print("%-7s %5s %8s %4s %9s %8s %8s %8s %7s %7s %9s %9s" % (
        "series", "procs", "contacts", "it", "solve s", "work s", "exch s", "ms/it", "speedup",
        "it-spd", "MB/proc", "checked"))
    for r in rows:
        print("%-7s %5d %8d %4d %9.2f %8.2f %8.2f %8.2f %7.2f %7.2f %9.1f %9.2e" % (
            r["series"], r["processes"], r["contacts"], r["iterations"], r["solve_seconds"],
            r["compute_seconds"], r["exchange_seconds"], r["per_iteration_ms"],
            r.get("speedup", float("nan")), r.get("per_iteration_speedup", float("nan")),
            r["peak_mb_per_process"], r["checked_error"] or float("nan")))
        if r.get("one_process"):
            p = r["one_process"]
            print("        one-process solver: %.2f s, %d iterations, %s, error %.2e" % (
                p["seconds"], p["iterations"], p["status"], p["error"]))
    if a.plot:
        plot(rows, a.plot, cores)


if __name__ == "__main__":
    main()
