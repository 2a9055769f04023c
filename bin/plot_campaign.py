#!/usr/bin/python3
"""Plots a campaign folder's campaign.csv: campaign.png, one column per model: the share of runs
that converged, the iterations of the converged runs, and every run's final pose error.
Usage: plot_campaign.py DIR [--title TITLE]. Needs Debian's python3-matplotlib (bin/setup)."""
import csv
import math
import os
import sys

from plot_common import dir_and_title, plt, save


def main():
    a = dir_and_title()
    path = os.path.join(a.dir, "campaign.csv")
    try:
        with open(path) as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        sys.exit(f"plot_campaign: {path}: {e.strerror}")
    if not rows:
        sys.exit(f"plot_campaign: {path} has no runs")
    models = list(dict.fromkeys(r["model"] for r in rows))
    fig, axes = plt.subplots(3, len(models), figsize=(3.2 * len(models), 7.5), squeeze=False)
    for c, m in enumerate(models):
        runs = [r for r in rows if r["model"] == m]
        conv = [r for r in runs if r["converged"] == "1"]
        ax = axes[0][c]
        ax.bar(["converged", "not"], [len(conv), len(runs) - len(conv)], color=["tab:green", "tab:red"])
        ax.set_title(f"{m}\n{len(conv)}/{len(runs)} converged", fontsize=9)
        ax.set_ylabel("runs")
        ax = axes[1][c]
        its = [int(r["iterations"]) for r in conv]
        if its:
            ax.hist(its, bins=min(20, max(3, len(its))), color="tab:blue")
        ax.set_xlabel("iterations (converged runs)")
        ax.set_ylabel("runs")
        ax = axes[2][c]
        err = [float(r["final_translation_mm"]) for r in runs]
        col = ["tab:green" if r["converged"] == "1" else "tab:red" for r in runs]
        ax.scatter(range(len(runs)), [max(e, 1e-3) if math.isfinite(e) else 1e3 for e in err], c=col, s=12)
        ax.set_yscale("log")
        ax.set_xlabel("run")
        ax.set_ylabel("final translation error (mm)")
    if a.title:
        fig.suptitle(a.title, fontsize=10)
    out = os.path.join(a.dir, "campaign.png")
    save(fig, out, dpi=100)
    print(f"plot_campaign: {out}")


if __name__ == "__main__":
    main()
