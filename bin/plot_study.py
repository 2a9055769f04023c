#!/usr/bin/python3
"""Plots a study folder's study.csv (cellsim study): study.png.
One axis: per model, against the axis (or against the measured depth spread, for an
object_scale or object_yaw axis): the share of runs that converged, the median iterations and final pose
error of those, and the median rise of |e| (0 for a monotonic decrease; oscillation piles it up).
Two axes: per model, a map of the converged share and one of the median rise of |e|.
Usage: plot_study.py DIR [--title TITLE]. Needs Debian's python3-matplotlib (bin/setup)."""
import csv
import json
import math
import os
import sys

from plot_common import dir_and_title, plt, save


def number(s):
    try:
        return float(s)
    except ValueError:
        return math.nan


def one_axis(rows, axis, models, title, out):
    x_key = "depth_spread_m" if axis.startswith("object_") else axis
    x_label = "depth spread at the desired pose (m)" if x_key == "depth_spread_m" else axis
    fig, axes = plt.subplots(1, 4, figsize=(17, 3.8))
    for m in models:
        rs = sorted((r for r in rows if r["model"] == m), key=lambda r: number(r[x_key]))
        x = [number(r[x_key]) for r in rs]
        axes[0].plot(x, [number(r["converged_pct"]) for r in rs], "o-", label=m)
        axes[1].plot(x, [number(r["median_iterations"]) for r in rs], "o-", label=m)
        axes[2].plot(x, [number(r["median_translation_mm"]) for r in rs], "o-", label=m)
        axes[3].plot(x, [number(r["median_error_rise"]) for r in rs], "o-", label=m)
    for ax, y in zip(axes, ("converged (%)", "median iterations (converged runs)",
                            "median final pose error (mm, converged runs)", "median rise of |e| / |e0|")):
        ax.set_xlabel(x_label)
        ax.set_ylabel(y)
        ax.grid(True, alpha=0.3)
    axes[0].set_ylim(-5, 105)
    axes[0].legend(fontsize=8)
    if title:
        fig.suptitle(title)
    save(fig, out)


def two_axes(rows, axes_names, models, title, out):
    a, b = axes_names
    xs = sorted({number(r[a]) for r in rows})
    ys = sorted({number(r[b]) for r in rows})
    fig, axes = plt.subplots(2, len(models), figsize=(3.6 * len(models), 6.6), squeeze=False)
    for c, m in enumerate(models):
        for row, key, cmap, label in ((0, "converged_pct", "RdYlGn", "converged (%)"),
                                      (1, "median_error_rise", "magma_r", "median rise of |e| / |e0|")):
            grid = [[math.nan] * len(xs) for _ in ys]
            for r in rows:
                if r["model"] == m:
                    grid[ys.index(number(r[b]))][xs.index(number(r[a]))] = number(r[key])
            ax = axes[row][c]
            im = ax.imshow(grid, origin="lower", aspect="auto", cmap=cmap,
                           vmin=0 if row == 0 else None, vmax=100 if row == 0 else None)
            ax.set_xticks(range(len(xs)), [f"{v:g}" for v in xs], fontsize=7)
            ax.set_yticks(range(len(ys)), [f"{v:g}" for v in ys], fontsize=7)
            ax.set_xlabel(a)
            ax.set_ylabel(b)
            ax.set_title(f"{m}: {label}", fontsize=8)
            for i, yrow in enumerate(grid):
                for j, v in enumerate(yrow):
                    if not math.isnan(v):
                        ax.text(j, i, f"{v:.0f}" if row == 0 else f"{v:.2f}", ha="center", va="center", fontsize=6)
            fig.colorbar(im, ax=ax, fraction=0.046)
    if title:
        fig.suptitle(title)
    save(fig, out)


def main():
    a = dir_and_title()
    try:
        with open(os.path.join(a.dir, "study.json")) as f:
            axes_names = [x["name"] for x in json.load(f)["axes"]]
        with open(os.path.join(a.dir, "study.csv")) as f:
            rows = list(csv.DictReader(f))
    except (OSError, ValueError, KeyError) as e:
        sys.exit(f"plot_study: {a.dir}: {e}")
    if not rows or len(axes_names) not in (1, 2):
        sys.exit(f"plot_study: {a.dir}: no rows, or not one or two axes")
    models = list(dict.fromkeys(r["model"] for r in rows))
    out = os.path.join(a.dir, "study.png")
    if len(axes_names) == 1:
        one_axis(rows, axes_names[0], models, a.title, out)
    else:
        two_axes(rows, axes_names, models, a.title, out)


if __name__ == "__main__":
    main()
