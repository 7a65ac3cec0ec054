#!/usr/bin/env python3
"""Two builds of libcadmm side by side in the Bullet or ODE driver: for each scene and seed, the
engine's own solver at 100 iterations (SI100: Bullet's sequential impulse, or ODE's QuickStep)
runs first; then cadmm with each library (through LD_LIBRARY_PATH, the
order alternating with the seed) at 1e-4 (or --tolerance), under SI100's mean step as the
budget unless other driver arguments are given, each step's error compared with SI100's at
the same step.

    python3 ab.py --driver build-bullet/cadmm_bullet_stack --before DIR --after DIR \\
        [--scenes wall,bin,chain,big-pyramid] [--seeds 1,2,3] [--rounds 2] [--tolerance 1e-8] \\
        [--scene-args "--count 30"] \\
        [--args "--time-limit 0.016"] [--budget-option=--step-time-limit] [--out ab.jsonl]

DIR holds a libcadmm.so.0. --before-driver and --after-driver run that side with another
build of the driver (a change to the drop-in itself); both default to --driver. Prints one
line per run and appends every run to --out (the per-step traces go to a temporary
directory).
"""
import argparse
import json
import os
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "..", "scripts"))
import engine_bench as eb  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--driver", required=True)
ap.add_argument("--before", required=True)
ap.add_argument("--after", required=True)
ap.add_argument("--before-driver", help="the driver for the before side (default --driver)")
ap.add_argument("--after-driver", help="the driver for the after side (default --driver)")
ap.add_argument("--scenes", default="wall,bin,chain,big-pyramid")
ap.add_argument("--seeds", default="1,2,3")
ap.add_argument("--args", default="", help="driver arguments instead of the budget")
ap.add_argument("--budget-option", default="--time-limit",
                help="the driver option the budget is given by (--step-time-limit: per step)")
ap.add_argument("--seconds", type=float, default=2.0)
ap.add_argument("--tolerance", default="1e-4", help="cadmm's tolerance on both sides")
ap.add_argument("--scene-args", default="",
                help="driver arguments for every run, the engine's too (--count 30: a scene's size)")
ap.add_argument("--rounds", type=int, default=1,
                help="runs of each side per seed, the order alternating from round to round")
ap.add_argument("--out", default="ab.jsonl")
a = ap.parse_args()
work = tempfile.mkdtemp(prefix="ab-traces-")  # the drivers' per-step CSVs
# The engine's own solver at 100 iterations: ODE's QuickStep with the ODE driver, Bullet's
# sequential impulse otherwise.
peer_args = (["--solver", "ode-quickstep", "--ode-iterations", "100"]
             if "ode" in os.path.basename(a.driver) else
             ["--solver", "bullet", "--bullet-iterations", "100"])
with open(a.out, "a") as log:
    for scene in a.scenes.split(","):
        for seed in map(int, a.seeds.split(",")):
            peer = os.path.join(work, f"{scene}-{seed}-si100.csv")
            si100 = eb.run(a.driver, scene, peer_args + ["--seed", str(seed)] + a.scene_args.split(),
                           a.seconds, 900, peer)
            budget = si100["mean_solve_ms"]
            limit = a.args.split() or [a.budget_option, f"{budget / 1e3:.6g}"]
            sides = [("before", "after") if (seed + k) % 2 else ("after", "before")
                     for k in range(a.rounds)]
            for rnd, name in ((k, n) for k, pair in enumerate(sides) for n in pair):
                trace = os.path.join(work, f"{scene}-{seed}-{name}-{rnd}.csv")
                env_lib = os.environ.get("LD_LIBRARY_PATH")
                os.environ["LD_LIBRARY_PATH"] = getattr(a, name)
                driver = getattr(a, f"{name}_driver") or a.driver
                r = eb.run(driver, scene, ["--solver", "cadmm", "--tolerance", a.tolerance,
                                             "--seed", str(seed)] + a.scene_args.split() + limit,
                           a.seconds, 900, trace)
                if env_lib is None:
                    del os.environ["LD_LIBRARY_PATH"]
                else:
                    os.environ["LD_LIBRARY_PATH"] = env_lib
                r.update(eb.compare_steps(trace, peer), **eb.budget_steps(trace, budget),
                         label=name, scene=scene, seed=seed, round=rnd, budget_ms=budget,
                         args=a.scene_args.split() + limit)
                log.write(json.dumps(r) + "\n")
                log.flush()
                print(f"{scene} {seed} {name}: budget {budget:.3f} ms, mean {r['mean_solve_ms']:.3f},"
                      f" median {r['median_solve_ms']:.3f}, setup {r.get('mean_setup_ms', float('nan')):.3f},"
                      f" longest {r['max_solve_ms']:.3f},"
                      f" within 1.1x budget {r['steps_within_budget']:.0%},"
                      f" below SI100 {r['steps_below_peer']:.0%}"
                      f" (+{r['steps_tied_at_round_off']:.0%} tied at round-off), median error"
                      f" {r['median_error']:.2e}, p95 {r['p95_error']:.2e}", flush=True)
