#!/usr/bin/python3
"""Plots a campaign folder's campaign.csv: campaign.png, one column per model: the share of runs
that converged, the iterations of the converged runs, every run's final pose error and, for
decoded features, the points each run's law took off their spot's centre (the simulator's truth).
Usage: plot_campaign.py DIR [--title TITLE]. Needs Debian's python3-matplotlib (bin/setup)."""
import csv
import json
import math
import os
import sys

from matplotlib.ticker import MaxNLocator

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
    # the truth of what the law took, for decoded features (ideal ones are the truth)
    truth = "off_centre_total" in rows[0] and decoded(a.dir)
    panels = 4 if truth else 3
    fig, axes = plt.subplots(panels, len(models), figsize=(max(3.2 * len(models), 6.4), 2.5 * panels), squeeze=False)
    # one scale per row across the models, so that 40 mm and 0.09 mm do not look alike
    shown = [max(float(r["final_translation_mm"]), 1e-3) if math.isfinite(float(r["final_translation_mm"])) else 1e3
             for r in rows]
    err_lim = (min(shown) / 1.5, max(shown) * 1.5)
    its_all = [int(r["iterations"]) for r in rows if r["converged"] == "1"]
    for c, m in enumerate(models):
        runs = [r for r in rows if r["model"] == m]
        conv = [r for r in runs if r["converged"] == "1"]
        ax = axes[0][c]
        ax.bar(["converged", "not"], [len(conv), len(runs) - len(conv)], color=["tab:green", "tab:red"])
        ax.set_title(f"{m}\n{len(conv)}/{len(runs)} converged", fontsize=9)
        ax.set_ylabel("runs")
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax = axes[1][c]
        its = [int(r["iterations"]) for r in conv]
        if its:
            ax.hist(its, bins=min(20, max(3, len(its))), range=(min(its_all), max(its_all) + 1), color="tab:blue")
        else:
            ax.text(0.5, 0.5, "no run converged", transform=ax.transAxes, ha="center", va="center", color="0.4")
            ax.set_xticks([])
            ax.set_yticks([])
        ax.set_xlabel("iterations (converged runs)")
        ax.set_ylabel("runs")
        if its:
            ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax = axes[2][c]
        err = [float(r["final_translation_mm"]) for r in runs]
        col = ["tab:green" if r["converged"] == "1" else "tab:red" for r in runs]
        ax.scatter(range(len(runs)), [max(e, 1e-3) if math.isfinite(e) else 1e3 for e in err], c=col, s=12)
        ax.set_yscale("log")
        ax.set_ylim(*err_lim)
        ax.set_xlabel("run")
        ax.set_ylabel("final translation error (mm)")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # runs are counted, not measured
        ax.grid(True, which="major", alpha=0.3)
        if truth:
            off_centre_panel(axes[3][c], runs, col)
    from matplotlib.lines import Line2D
    axes[2][0].legend(handles=[Line2D([], [], ls="", marker="o", color="tab:green", label="converged"),
                               Line2D([], [], ls="", marker="o", color="tab:red", label="not converged")],
                      fontsize=7, loc="best")
    if a.title:
        fig.suptitle(a.title, fontsize=10)
    out = os.path.join(a.dir, "campaign.png")
    save(fig, out, dpi=100, top=0.95 if a.title else 1.0)
    print(f"plot_campaign: {out}")


def decoded(folder):
    """Whether the campaign in `folder` ran on decoded features (campaign.json says)."""
    try:
        with open(os.path.join(folder, "campaign.json")) as f:
            return json.load(f).get("features") == "decoded"
    except (OSError, ValueError, AttributeError):
        return False


def off_centre_panel(ax, runs, colours):
    """Per run, the points its law took off their spot's centre, summed over its iterations."""
    ax.bar(range(len(runs)), [int(r["off_centre_total"]) for r in runs], color=colours)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("run")
    ax.set_ylabel("law's points off their\nspot's centre (run total)")
    ax.grid(True, axis="y", alpha=0.3)


if __name__ == "__main__":
    main()
