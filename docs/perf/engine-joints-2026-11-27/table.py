#!/usr/bin/env python3
"""The tables of summary.md from scripts/engine_bench.py's engine.jsonl: per scene and solver,
the median over the repeats of each figure of the driver's JSON line.

    python3 docs/perf/engine-joints-2026-11-27/table.py target/engine-joints/engine.jsonl
"""
import json
import statistics
import sys

ORDER = ["cadmm 1e-8", "cadmm 1e-4", "Bullet SI10", "Bullet SI100"]


def main(path):
    runs = {}
    for line in open(path):
        r = json.loads(line)
        if "steps" in r:  # a run that ended with its JSON line
            runs.setdefault((r["scene"], r["label"]), []).append(r)

    def med(rs, key):
        xs = [r[key] for r in rs if r.get(key) is not None]
        return statistics.median(xs) if xs else None

    def g(x, fmt="{:.3g}"):
        return "-" if x is None else ("{:.0f}" if abs(x) >= 1000 else fmt).format(x)

    for scene in sorted({s for s, _ in runs}):
        arm = scene == "arm"
        print(f"\n{scene} (medians of {len(runs[(scene, ORDER[0])])} runs)\n")
        print("| solver | mean / p99 / longest step (ms) | iterations mean / max | worst error | "
              "unsolved | " + ("tip drift end / max (mm) | " if arm else "new solvers | ") +
              "joint gap (mm) | deepest penetration (mm) |")
        print("|---" * 8 + "|")
        for label in ORDER:
            rs = runs.get((scene, label))
            if not rs:
                continue
            # cadmm's answers as the driver re-measures them, Bullet's by cadmm_problem_error:
            # the same measure (bullet_reference_solver.h, solution_check.h).
            err = med(rs, "max_checked_error" if label.startswith("cadmm") else "max_error")
            mm = lambda k: None if med(rs, k) is None else 1e3 * med(rs, k)
            extra = (f"{g(med(rs, 'tip_drift_mm'))} / {g(med(rs, 'max_tip_drift_mm'))}" if arm
                     else g(med(rs, "new_solvers"), "{:.0f}"))
            print(f"| {label} | {g(med(rs, 'mean_solve_ms'))} / {g(med(rs, 'p99_solve_ms'))} / "
                  f"{g(med(rs, 'max_solve_ms'))} | {g(med(rs, 'mean_iterations'))} / "
                  f"{g(med(rs, 'max_iterations'), '{:.0f}')} | {g(err, '{:.1e}')} | "
                  f"{g(med(rs, 'unsolved_steps'), '{:.0f}')} | {extra} | "
                  f"{g(mm('max_joint_gap'))} | {g(mm('max_penetration'))} |")


if __name__ == "__main__":
    main(sys.argv[1])
