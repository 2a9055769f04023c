#!/usr/bin/python3
"""Plots an experiment's trace.csv like the paper's Fig. 4c-d / 5d-i:
velocities.png (camera velocities vs time) and error_norm.png (norm of the task function).
Usage: plot_trace.py DIR [--title TITLE]. Needs Debian's python3-matplotlib (bin/setup)."""
import argparse
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_trace(path):
    with open(path) as f:
        lines = [line for line in f if not line.startswith("#")]
    rows = list(csv.DictReader(lines))
    if not rows:
        sys.exit(f"plot_trace: {path} has no iterations")
    return {k: [float(r[k]) for r in rows] for k in rows[0]}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--title", default="")
    args = ap.parse_args()
    trace = os.path.join(args.dir, "trace.csv")
    if not os.path.exists(trace):
        sys.exit(f"plot_trace: {trace} not found")
    t = read_trace(trace)

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for key, style in (("vx", "-"), ("vy", "-"), ("vz", "-"), ("wx", "--"), ("wy", "--"), ("wz", "--")):
        ax.plot(t["t"], t[key], style, label=key + (" (m/s)" if key[0] == "v" else " (rad/s)"))
    ax.set_xlabel("time (s)")
    ax.set_ylabel("camera velocity (m/s, rad/s)")
    ax.set_title(f"{args.title}: camera velocities" if args.title else "camera velocities")
    ax.grid(True, alpha=0.3)
    ax.legend(ncol=2, fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(args.dir, "velocities.png"), dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.plot(t["t"], t["error_norm"], color="k")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("|e|")
    ax.set_yscale("log")
    ax.set_title(f"{args.title}: norm of the task function" if args.title else "norm of the task function")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(args.dir, "error_norm.png"), dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
