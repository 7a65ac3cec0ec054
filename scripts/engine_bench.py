#!/usr/bin/env python3
"""The engine benchmark: every scene of an integration's driver (integrations/bullet's
cadmm_bullet_stack, integrations/ode's cadmm_ode_stack) run with cadmm at 1e-4, 1e-6 and
1e-8, with cadmm under a time budget, and with the engine's own solver at 10 and 100
iterations (Bullet's sequential impulse, ODE's QuickStep), side by side in one run, each
configuration `--repeats` times (medians reported).

    python3 scripts/engine_bench.py --driver build-bullet/cadmm_bullet_stack \\
        [--scenes wall,bin,chain,big-pyramid] [--solvers "cadmm 1e-4,Bullet SI100"]
        [--seconds 3] [--repeats 3] [--out DIR]
    python3 scripts/engine_bench.py --driver build-ode/cadmm_ode_stack [...]

The engine is told by the driver's name. "cadmm budget" runs cadmm at 1e-4 with its time
limit (SolverOptions::timeLimit, cadmm_ode_options.time_limit) set to the mean step of the
same repeat's run of the engine's solver at 100 iterations (which runs first), and
compares the two runs step by step: the share of steps whose answer measures below SI100's at the same step, and the
median and 95th percentile of the steps' errors; and the share of its steps that end
within 1.1 times the budget.

Per scene and solver: mean, p99 and longest step (ms of solveGroup, medians over the
repeats), cadmm's mean setup within the step (assembly, solver built or updated, warm start:
what comes before the solve), the worst error of the answers by the common measure (cadmm_problem_error on the
problem of each group: cadmm's own answers re-measured by the driver, Bullet's measured on
the velocity-level problem it solves), unsolved steps, and the physics (deepest penetration,
largest joint gap). Writes DIR/engine.jsonl (every run), DIR/engine.md (the table) and
DIR/engine.png (mean step time against worst error, one panel per scene).
"""
import argparse
import csv
import json
import os
import statistics
import subprocess
import sys

CADMM = [
    ("cadmm 1e-4", ["--solver", "cadmm", "--tolerance", "1e-4"]),
    ("cadmm 1e-6", ["--solver", "cadmm", "--tolerance", "1e-6"]),
    ("cadmm 1e-8", ["--solver", "cadmm", "--tolerance", "1e-8"]),
]
# Per engine: its solver at 10 and 100 iterations; the second is the budget's peer.
PEERS = {
    "bullet": [("Bullet SI10", ["--solver", "bullet", "--bullet-iterations", "10"]),
               ("Bullet SI100", ["--solver", "bullet", "--bullet-iterations", "100"])],
    "ode": [("ODE QS10", ["--solver", "ode-quickstep", "--ode-iterations", "10"]),
            ("ODE QS100", ["--solver", "ode-quickstep", "--ode-iterations", "100"])],
}
# Its --time-limit is the peer's mean step of the same repeat, added at run time.
BUDGET = ("cadmm budget", ["--solver", "cadmm", "--tolerance", "1e-4"])


def solvers_of(engine):
    """The configurations run for `engine`, the budget's peer last before the budget."""
    return CADMM + PEERS[engine] + [BUDGET]


def step_errors(trace):
    """The error of each step of a driver's --trace CSV."""
    with open(trace) as f:
        return [float(row["error"]) for row in csv.DictReader(f)]


# Both answers at or below this error are exact to round-off (the measure is relative, and
# its floor in double precision is about 1e-16 times the problem's conditioning): such a
# step is a tie, not a loss, whichever of the two round-off errors is smaller.
ROUND_OFF = 1e-14


def compare_steps(budget_trace, peer_trace):
    """Share of steps whose budgeted answer measures below the peer's, share of steps where
    both are exact to round-off (a tie), and the budgeted run's median and 95th percentile
    step error."""
    ours, peer = step_errors(budget_trace), step_errors(peer_trace)
    n = min(len(ours), len(peer))
    ranked = sorted(ours)
    tied = sum(a <= ROUND_OFF and b <= ROUND_OFF and a >= b for a, b in zip(ours, peer))
    return {"steps_below_peer": sum(a < b for a, b in zip(ours, peer)) / n if n else None,
            "steps_tied_at_round_off": tied / n if n else None,
            "median_error": ranked[len(ranked) // 2] if ranked else None,
            "p95_error": ranked[int(0.95 * len(ranked))] if ranked else None}


# A budgeted step "ends within the budget" when it takes at most this many times it.
BUDGET_SLACK = 1.1


def budget_steps(trace, budget_ms):
    """The share of a budgeted run's steps that end within BUDGET_SLACK times the budget, and
    its median step (ms): the mean alone carries one-time costs (the first step builds the
    solver) that a short run does not amortize."""
    with open(trace) as f:
        steps = [float(row["solve_ms"]) for row in csv.DictReader(f)]
    within = sum(t <= BUDGET_SLACK * budget_ms for t in steps)
    return {"steps_within_budget": within / len(steps) if steps else None,
            "median_solve_ms": statistics.median(steps) if steps else None}


def run(driver, scene, args, seconds, timeout, trace=None):
    cmd = [driver, "--scene", scene, "--seconds", str(seconds), "--json"] + args
    if trace:
        cmd += ["--trace", trace]
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
    ap.add_argument("--driver", required=True, help="cadmm_bullet_stack or cadmm_ode_stack")
    ap.add_argument("--scenes", default="wall,bin,chain,big-pyramid")
    ap.add_argument("--solvers", default=None,
                    help="comma-separated labels of the configurations to run (default all)")
    ap.add_argument("--seconds", type=float, default=3.0, help="simulated seconds per run")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=900, help="wall seconds per run")
    ap.add_argument("--out", default="target/engine-bench")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    engine = "ode" if "ode" in os.path.basename(a.driver) else "bullet"
    solvers = solvers_of(engine)
    peer = PEERS[engine][-1][0]
    wanted = a.solvers.split(",") if a.solvers else [name for name, _ in solvers]
    chosen = [(name, args) for name, args in solvers if name in wanted]
    if not chosen:
        ap.error(f"--solvers: none of {wanted!r} is one of {[n for n, _ in solvers]}")
    names = [name for name, _ in chosen]
    if BUDGET[0] in names and peer not in names:
        ap.error(f"--solvers: \"{BUDGET[0]}\" takes its budget from \"{peer}\"")
    rows, table = [], {}
    with open(os.path.join(a.out, "engine.jsonl"), "w") as log:
        for scene in a.scenes.split(","):
            for rep in range(a.repeats):  # interleaved: the machine's load hits all alike
                peer_run = None
                for name, args in chosen:
                    trace = os.path.join(a.out, f"{scene}-{name.replace(' ', '-')}-{rep}.csv")
                    if name == "cadmm budget":
                        budget = (peer_run or {}).get("mean_solve_ms")
                        if budget is None:
                            continue
                        args = args + ["--time-limit", f"{budget / 1e3:.6g}"]
                    r = run(a.driver, scene, args, a.seconds, a.timeout, trace)
                    if name == peer:
                        peer_run = dict(r, trace=trace)
                    if name == "cadmm budget" and "steps" in r:
                        r.update(budget_ms=budget, **compare_steps(trace, peer_run["trace"]),
                                 **budget_steps(trace, budget))
                    r.update(label=name, repeat=rep, scene=scene)
                    log.write(json.dumps(r) + "\n")
                    log.flush()
                    table.setdefault((scene, name), []).append(r)
                    print(f"{scene:12} {name:12} rep {rep}: mean {r.get('mean_solve_ms')} ms, "
                          f"max {r.get('max_solve_ms')} ms, error {r.get('max_error')}",
                          file=sys.stderr, flush=True)
    lines = ["| scene | solver | mean step (ms) | of which setup (ms) | p99 (ms) | longest (ms) | "
             f"worst error | median / p95 step error | steps below {peer} (+ tied at round-off) | "
             "steps within 1.1 x budget | unsolved steps | "
             "deepest penetration (m) | joint gap (m) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for (scene, name), runs in table.items():
        ok = [r for r in runs if "steps" in r]
        if not ok:
            why = "timed out" if runs[0].get("timeout") else runs[0].get("failed", "failed")
            lines.append(f"| {scene} | {name} | {why} | | | | | | | | | | |")
            continue
        f = lambda k, fmt="{:.3g}": (fmt.format(median(ok, k)) if median(ok, k) is not None else "-")
        lines.append(f"| {scene} | {name} | {f('mean_solve_ms')} | {f('mean_setup_ms')} | "
                     f"{f('p99_solve_ms')} | "
                     f"{f('max_solve_ms')} | {f('max_error', '{:.1e}')} | "
                     f"{f('median_error', '{:.1e}')} / {f('p95_error', '{:.1e}')} | "
                     f"{f('steps_below_peer', '{:.0%}')} "
                     f"(+{f('steps_tied_at_round_off', '{:.0%}')}) | "
                     f"{f('steps_within_budget', '{:.0%}')} | "
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
