#!/usr/bin/python3
"""Plots cadmm_bullet_stack --trace CSV files side by side: per-step solve time, iterations
and the top body's height against time.

    plot_trace.py OUT.png LABEL=trace.csv [LABEL=trace.csv ...] [--title TITLE]
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: [float(r[k]) if r[k] != "null" else float("nan") for r in rows] for k in rows[0]}


def main(argv):
    if len(argv) < 3:
        sys.exit(__doc__)
    title = None
    if "--title" in argv:
        i = argv.index("--title")
        title = argv[i + 1]
        del argv[i : i + 2]
    out, runs = argv[1], [a.split("=", 1) for a in argv[2:]]
    fig, axes = plt.subplots(3, 1, figsize=(7, 7.5), sharex=True)
    for label, path in runs:
        t = read(path)
        axes[0].plot(t["time"], t["solve_ms"], label=label, lw=1)
        axes[1].plot(t["time"], t["iterations"], label=label, lw=1)
        axes[2].plot(t["time"], t["top_height"], label=label, lw=1)
    axes[0].set_ylabel("solve time per step (ms)")
    axes[0].set_yscale("log")
    axes[1].set_ylabel("iterations per step")
    axes[1].set_yscale("log")
    axes[2].set_ylabel("top body height (m)")
    axes[2].set_xlabel("simulated time (s)")
    axes[0].legend(fontsize=8)
    for ax in axes:
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out, dpi=80)


if __name__ == "__main__":
    main(sys.argv)
