#!/usr/bin/python3
"""Plots cadmm_ode_stack --trace CSV files side by side: per-step solve time, iterations
and the top body's height against simulated time.

    plot_trace.py OUT.png "cadmm=tower_cadmm.csv" "ODE QuickStep=tower_quick.csv" ...

Needs matplotlib (Debian: python3-matplotlib, for /usr/bin/python3). The solve time is
the CPU time of the step's contact solve.
"""
import csv
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    cols = {}
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            for k, v in row.items():
                cols.setdefault(k, []).append(float(v))
    return cols


def main(argv):
    if len(argv) < 3 or any("=" not in a for a in argv[2:]):
        sys.exit(__doc__)
    out, runs = argv[1], [a.split("=", 1) for a in argv[2:]]
    fig, axes = plt.subplots(3, 1, figsize=(7, 7.5), sharex=True)
    for label, path in runs:
        t = read(path)
        time = t["time"]
        axes[0].plot(time, t["solve_cpu_ms"], label=label, lw=0.9)
        if not all(math.isnan(i) for i in t["iterations"]):
            axes[1].plot(time, t["iterations"], label=label, lw=0.9)
        axes[2].plot(time, t["top_z"], label=label, lw=0.9)
    axes[0].set_yscale("log")
    axes[0].set_ylabel("solve CPU time per step (ms)")
    axes[1].set_ylabel("cadmm iterations")
    axes[2].set_ylabel("top body height (m)")
    axes[2].set_xlabel("simulated time (s)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=80)


if __name__ == "__main__":
    main(sys.argv)
