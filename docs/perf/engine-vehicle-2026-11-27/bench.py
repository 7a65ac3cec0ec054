#!/usr/bin/env python3
"""The ODE vehicle side by side: cadmm_ode_stack --scene vehicle with cadmm at 1e-8 and 1e-4,
ODE's dWorldQuickStep at 20 (its default) and 100 iterations and dWorldStep, interleaved
(every solver once, then again: the machine's load hits all alike), `--repeats` times.
Writes OUT/vehicle.jsonl (every run's JSON line, with its label and repeat) and OUT/*.csv
(every run's --trace), then prints the tables of summary.md: per solver the median over
the repeats of each figure, and for cadmm the cost by phase of the drive and its slowest
steps.

    python3 docs/perf/engine-vehicle-2026-11-27/bench.py --driver build-ode/cadmm_ode_stack \\
        [--seconds 5] [--repeats 3] [--out target/engine-vehicle]
"""
import argparse
import csv
import json
import os
import statistics
import subprocess

SOLVERS = [
    ("cadmm 1e-8", ["--solver", "cadmm"]),
    ("cadmm 1e-4", ["--solver", "cadmm", "--tolerance", "1e-4"]),
    ("QuickStep 20", ["--solver", "ode-quickstep"]),
    ("QuickStep 100", ["--solver", "ode-quickstep", "--ode-iterations", "100"]),
    ("dWorldStep", ["--solver", "ode-step"]),
]

# Steps of the drive (60 Hz, scenes.c): accelerating on the flat until the front wheels
# reach the bump (step 56), over the bump until the rear wheels have landed (step 110),
# then on to 6 m/s (reached about step 125) and cruising.
PHASES = [("accelerating, flat (steps 0-55)", 0, 56), ("bump (steps 56-110)", 56, 111),
          ("after the bump (steps 111-299)", 111, 300)]


def med(rs, key):
    xs = [r[key] for r in rs if r.get(key) is not None]
    return statistics.median(xs) if xs else None


def g(x, fmt="{:.3g}"):
    return "-" if x is None else fmt.format(x)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--driver", required=True, help="cadmm_ode_stack")
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default="target/engine-vehicle")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    runs = {}
    with open(os.path.join(a.out, "vehicle.jsonl"), "w") as log:
        for rep in range(a.repeats):
            for label, args in SOLVERS:
                trace = os.path.join(a.out, f"{label.replace(' ', '-')}-{rep}.csv")
                cmd = [a.driver, "--scene", "vehicle", "--seconds", str(a.seconds), "--json",
                       "--trace", trace] + args
                out = subprocess.run(cmd, capture_output=True, text=True, check=True)
                r = json.loads([l for l in out.stdout.splitlines() if l.startswith("{")][-1])
                r.update(label=label, repeat=rep, trace=trace)
                log.write(json.dumps(r) + "\n")
                runs.setdefault(label, []).append(r)

    print(f"Medians of {a.repeats} runs, {a.seconds:g} s at 60 Hz.\n")
    print("| solver | mean / p99 / longest step (ms) | mean step CPU (ms) | iterations mean / max "
          "| worst error | unsolved |")
    print("|---|---|---|---|---|---|")
    for label, _ in SOLVERS:
        rs = runs[label]
        cadmm = label.startswith("cadmm")
        # cadmm's answers as check.c re-measures them; ODE's by the same measure (check.c)
        # with its multipliers recovered from its joints' feedback.
        print(f"| {label} | {g(med(rs, 'mean_solve_ms'))} / {g(med(rs, 'p99_solve_ms'))} / "
              f"{g(med(rs, 'max_solve_ms'))} | {g(med(rs, 'mean_solve_cpu_ms'))} | "
              + (f"{g(med(rs, 'mean_iterations'))} / {g(med(rs, 'max_iterations'), '{:.0f}')} | "
                 if cadmm else "- | ")
              + f"{g(med(rs, 'max_checked_error'), '{:.1e}')} | "
              + (f"{g(med(rs, 'unsolved_steps'), '{:.0f}')} |" if cadmm else "- |"))
    mm = lambda rs, k: None if med(rs, k) is None else 1e3 * med(rs, k)
    print("\n| solver | joint gap (mm) | axes off square / steering (rad) | suspension travel "
          "(mm) | deepest penetration (mm) | distance (m) | final speed (m/s) | over the "
          "bump at (s) |")
    print("|---|---|---|---|---|---|---|---|")
    for label, _ in SOLVERS:
        rs = runs[label]
        print(f"| {label} | {g(mm(rs, 'max_joint_gap'))} | {g(med(rs, 'max_axis_error'), '{:.1e}')}"
              f" / {g(med(rs, 'max_steer'), '{:.1e}')} | {g(mm(rs, 'max_suspension_travel'))} | "
              f"{g(mm(rs, 'max_penetration'))} | {g(med(rs, 'distance'), '{:.4g}')} | "
              f"{g(med(rs, 'final_speed'))} | {g(med(rs, 'over_bump_time'))} |")
    print("\n| solver | chassis z min / max (m) | on the bump: z min / max (m) | largest pitch "
          "(rad) | on the bump | largest roll (rad) |")
    print("|---|---|---|---|---|---|")
    for label, _ in SOLVERS:
        rs = runs[label]
        print(f"| {label} | {g(med(rs, 'min_chassis_z'), '{:.4g}')} / "
              f"{g(med(rs, 'max_chassis_z'), '{:.4g}')} | "
              f"{g(med(rs, 'bump_min_chassis_z'), '{:.4g}')} / "
              f"{g(med(rs, 'bump_max_chassis_z'), '{:.4g}')} | {g(med(rs, 'max_pitch'))} | "
              f"{g(med(rs, 'bump_max_pitch'))} | {g(med(rs, 'max_roll'), '{:.1e}')} |")

    # Where each solver's answers measure worst (the first repeat; the runs are
    # deterministic but for cadmm's timing).
    print("\n| solver | steps measuring above 1e-6 | worst step: error, contacts | "
          "median / p95 step error |")
    print("|---|---|---|---|")
    for label, _ in SOLVERS:
        t = list(csv.DictReader(open(runs[label][0]["trace"])))
        worst = max(t, key=lambda row: float(row["error"]))
        errors = sorted(float(row["error"]) for row in t)
        print(f"| {label} | {sum(e > 1e-6 for e in errors)} | step "
              f"{worst['step']}: {float(worst['error']):.1e}, {worst['contacts']} | "
              f"{errors[len(errors) // 2]:.1e} / {errors[int(0.95 * len(errors))]:.1e} |")

    # cadmm per phase (medians over the repeats of each phase's mean) and its slowest steps.
    for label in ("cadmm 1e-8", "cadmm 1e-4"):
        print(f"\n{label} by phase: mean step ms / CPU ms / iterations mean, max")
        traces = [list(csv.DictReader(open(r["trace"]))) for r in runs[label]]
        for name, lo, hi in PHASES:
            def phase(key, f):
                return statistics.median(f([float(row[key]) for row in t[lo:hi]]) for t in traces)
            print(f"  {name}: {phase('solve_ms', statistics.mean):.3g} / "
                  f"{phase('solve_cpu_ms', statistics.mean):.3g} / "
                  f"{phase('iterations', statistics.mean):.3g}, {phase('iterations', max):.0f}")
        print("  slowest steps (CPU ms of each repeat): step, iterations, contacts, error")
        worst = sorted(traces[0], key=lambda row: -float(row["solve_cpu_ms"]))[:5]
        for row in sorted(worst, key=lambda row: int(row["step"])):
            k = int(row["step"])
            cpu = ", ".join(f"{float(t[k]['solve_cpu_ms']):.2f}" for t in traces)
            print(f"    step {k}: {cpu} ms; {row['iterations']} iterations, "
                  f"{row['contacts']} contacts, error {float(row['error']):.1e}")


if __name__ == "__main__":
    main()
