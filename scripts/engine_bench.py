#!/usr/bin/env python3
"""The engine benchmark: every Bullet scene of integrations/bullet run with cadmm at 1e-4,
1e-6 and 1e-8 and with Bullet's sequential impulse at 10 and 100 iterations, side by side in
one run, each configuration `--repeats` times (medians reported).

    python3 scripts/engine_bench.py --driver build-bullet/cadmm_bullet_stack \\
        [--scenes wall,bin,chain,big-pyramid] [--solvers "cadmm 1e-4,Bullet SI100"]
        [--seconds 3] [--repeats 3] [--out DIR]

Per scene and solver: mean, p99 and longest step (ms of solveGroup, medians over the
repeats), the worst error of the answers by the common measure (cadmm_problem_error on the
problem of each group: cadmm's own answers re-measured by the driver, Bullet's measured on
the velocity-level problem it solves), unsolved steps, and the physics (deepest penetration,
largest joint gap). Writes DIR/engine.jsonl (every run), DIR/engine.md (the table) and
DIR/engine.png (mean step time against worst error, one panel per scene).
"""
import argparse
import json
import os
import statistics
import subprocess
import sys

SOLVERS = [
    ("cadmm 1e-4", ["--solver", "cadmm", "--tolerance", "1e-4"]),
    ("cadmm 1e-6", ["--solver", "cadmm", "--tolerance", "1e-6"]),
    ("cadmm 1e-8", ["--solver", "cadmm", "--tolerance", "1e-8"]),
    ("Bullet SI10", ["--solver", "bullet", "--bullet-iterations", "10"]),
    ("Bullet SI100", ["--solver", "bullet", "--bullet-iterations", "100"]),
]


def run(driver, scene, args, seconds, timeout):
    cmd = [driver, "--scene", scene, "--seconds", str(seconds), "--json"] + args
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"timeout": True}
    lines = [l for l in out.stdout.splitlines() if l.startswith("{")]
    if out.returncode != 0 or not lines:
        return {"failed": out.stderr.strip()[-300:] or f"exit {out.returncode}"}
    return json.loads(lines[-1])


def median(runs, key):
    xs = [r[key] for r in runs if r.get(key) is not None]
    return statistics.median(xs) if xs else None


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--driver", required=True, help="cadmm_bullet_stack")
    ap.add_argument("--scenes", default="wall,bin,chain,big-pyramid")
    ap.add_argument("--solvers", default=",".join(name for name, _ in SOLVERS),
                    help="comma-separated labels of SOLVERS to run")
    ap.add_argument("--seconds", type=float, default=3.0, help="simulated seconds per run")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=900, help="wall seconds per run")
    ap.add_argument("--out", default="target/engine-bench")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    chosen = [(name, args) for name, args in SOLVERS if name in a.solvers.split(",")]
    if not chosen:
        ap.error(f"--solvers: none of {a.solvers!r} is one of {[n for n, _ in SOLVERS]}")
    rows, table = [], {}
    with open(os.path.join(a.out, "engine.jsonl"), "w") as log:
        for scene in a.scenes.split(","):
            for rep in range(a.repeats):  # interleaved: the machine's load hits all alike
                for name, args in chosen:
                    r = run(a.driver, scene, args, a.seconds, a.timeout)
                    r.update(label=name, repeat=rep, scene=scene)
                    log.write(json.dumps(r) + "\n")
                    log.flush()
                    table.setdefault((scene, name), []).append(r)
                    print(f"{scene:12} {name:12} rep {rep}: mean {r.get('mean_solve_ms')} ms, "
                          f"max {r.get('max_solve_ms')} ms, error {r.get('max_error')}",
                          file=sys.stderr, flush=True)
    lines = ["| scene | solver | mean step (ms) | p99 (ms) | longest (ms) | worst error | "
             "unsolved steps | deepest penetration (m) | joint gap (m) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for (scene, name), runs in table.items():
        ok = [r for r in runs if "steps" in r]
        if not ok:
            why = "timed out" if runs[0].get("timeout") else runs[0].get("failed", "failed")
            lines.append(f"| {scene} | {name} | {why} | | | | | | |")
            continue
        f = lambda k, fmt="{:.3g}": (fmt.format(median(ok, k)) if median(ok, k) is not None else "-")
        lines.append(f"| {scene} | {name} | {f('mean_solve_ms')} | {f('p99_solve_ms')} | "
                     f"{f('max_solve_ms')} | {f('max_error', '{:.1e}')} | "
                     f"{f('unsolved_steps', '{:.0f}')} | {f('max_penetration')} | "
                     f"{f('max_joint_gap')} |")
        rows.append((scene, name, median(ok, "mean_solve_ms"), median(ok, "max_error")))
    with open(os.path.join(a.out, "engine.md"), "w") as md:
        md.write("\n".join(lines) + "\n")
    print("\n".join(lines))
    plot(rows, os.path.join(a.out, "engine.png"))


def plot(rows, path):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("engine_bench: no matplotlib, no plot", file=sys.stderr)
        return
    scenes = sorted({r[0] for r in rows})
    fig, axes = plt.subplots(1, len(scenes), figsize=(4 * len(scenes), 3.5), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        for _, name, ms, err in (r for r in rows if r[0] == scene):
            if ms and err:
                ax.loglog([err], [ms], "o" if name.startswith("cadmm") else "s", label=name)
        ax.set_title(scene)
        ax.set_xlabel("worst error (common measure)")
        ax.set_ylabel("mean step (ms)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
