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


# The study axes (cellsim study --axis NAME=...), named with their units on the plots; a name not
# here is shown as it is
AXIS_LABELS = {
    "z_hat": "Ẑ, the law's constant depth (m)",
    "gain": "gain λ",
    "object_scale_x": "object scale along x (×)", "object_scale_y": "object scale along y (×)",
    "object_scale_z": "object scale along z (×)",
    "object_yaw_deg": "object yaw (deg)",
    "error_scale": "calibration errors (× the drawn ones)",
    "offset_scale": "initial offset (× the paper's)",
    "outliers": "ids swapped per frame (share)",
    "losses": "decoded spots dropped per frame (share)",
    "focal_pct": "focal length error (%)", "principal_point_px": "principal point error (px)",
    "distortion_k1": "k1 error", "projector_position_mm": "projector position error (mm)",
    "projector_rotation_deg": "projector rotation error (deg)", "hand_eye_position_mm": "hand-eye position error (mm)",
    "hand_eye_rotation_deg": "hand-eye rotation error (deg)", "link_length_pct": "link length error (%)",
    "joint_offset_deg": "joint offset error (deg)",
    "acquisition_frames": "acquisition delay (frames)", "processing_frames": "processing delay (frames)",
    "actuation_s": "actuation delay (s)",
    "visual_features": "visual features",
}


def label(axis):
    return AXIS_LABELS.get(axis, axis)


# an axis of names (study.csv holds their index): its ticks are the names
NAMED_AXES = {"visual_features": ["points", "moments", "surface", "plane"]}


def tick_names(axis, values):
    names = NAMED_AXES.get(axis)
    return [names[int(v)] if names and 0 <= int(v) < len(names) else f"{v:g}" for v in values]


def cell_text_colour(im, v):
    """Black on a light cell, white on a dark one (the colour map's luminance there)."""
    r, g, b, _ = im.cmap(im.norm(v))
    return "black" if 0.299 * r + 0.587 * g + 0.114 * b > 0.5 else "white"


def one_axis(rows, axis, models, title, out):
    x_key = "depth_spread_m" if axis.startswith("object_") else axis
    x_label = "depth spread at the desired pose (m)" if x_key == "depth_spread_m" else label(axis)
    fig, axes = plt.subplots(1, 4, figsize=(17, 3.8), sharex=True)
    # models that give the same value draw on one another: each its own marker, a smaller one
    # drawn over a larger, hollow one, and its own line style, so every model stays visible
    looks = [dict(marker=mk, markersize=ms, linestyle=ls, fillstyle=fs)
             for mk, ms, ls, fs in (("o", 11, "-", "none"), ("s", 8, "--", "none"), ("^", 6, "-.", "full"),
                                    ("D", 4, ":", "full"))]
    for i, m in enumerate(models):
        rs = sorted((r for r in rows if r["model"] == m), key=lambda r: number(r[x_key]))
        x = [number(r[x_key]) for r in rs]
        look = looks[i % len(looks)]
        axes[0].plot(x, [number(r["converged_pct"]) for r in rs], label=m, **look)
        axes[1].plot(x, [number(r["median_iterations"]) for r in rs], label=m, **look)
        axes[2].plot(x, [number(r["median_translation_mm"]) for r in rs], label=m, **look)
        axes[3].plot(x, [number(r["median_error_rise"]) for r in rs], label=m, **look)
    for ax, y in zip(axes, ("converged (%)", "iterations (median, converged)",
                            "final error (mm, median, converged)", "rise of |e| / |e0| (median)")):
        if axis in NAMED_AXES:
            values = sorted({number(r[x_key]) for r in rows})
            ax.set_xticks(values, tick_names(axis, values))
        ax.set_xlabel(x_label)
        ax.set_ylabel(y)
        ax.grid(True, alpha=0.3)
    # a panel of the converged runs' figures when none converged: said, not an empty axis
    for ax, key in ((axes[1], "median_iterations"), (axes[2], "median_translation_mm")):
        if all(math.isnan(number(r[key])) for r in rows):
            ax.text(0.5, 0.5, "no run converged", transform=ax.transAxes, ha="center", va="center", color="0.4")
            ax.set_yticks([])
    axes[0].set_ylim(-5, 105)
    # the models' legend below the panels: inside one it covered the lines
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=9, frameon=False)
    if title:
        fig.suptitle(title, fontsize=11)
    save(fig, out, top=0.9 if title else 1.0, bottom=0.1)


def two_axes(rows, axes_names, models, title, out):
    a, b = axes_names
    xs = sorted({number(r[a]) for r in rows})
    ys = sorted({number(r[b]) for r in rows})
    fig, axes = plt.subplots(2, len(models), figsize=(max(4.2 * len(models), 6.0), 7.0), squeeze=False)
    for c, m in enumerate(models):
        for row, key, cmap, what in ((0, "converged_pct", "RdYlGn", "converged (%)"),
                                     (1, "median_error_rise", "magma_r", "median rise of |e| / |e0|")):
            grid = [[math.nan] * len(xs) for _ in ys]
            for r in rows:
                if r["model"] == m:
                    grid[ys.index(number(r[b]))][xs.index(number(r[a]))] = number(r[key])
            ax = axes[row][c]
            im = ax.imshow(grid, origin="lower", aspect="auto", cmap=cmap,
                           vmin=0 if row == 0 else None, vmax=100 if row == 0 else None)
            ax.set_xticks(range(len(xs)), tick_names(a, xs), fontsize=7)
            ax.set_yticks(range(len(ys)), tick_names(b, ys), fontsize=7)
            ax.set_xlabel(label(a), fontsize=8)
            ax.set_ylabel(label(b), fontsize=8)
            ax.set_title(f"{m}:\n{what}", fontsize=8)
            for i, yrow in enumerate(grid):
                for j, v in enumerate(yrow):
                    if not math.isnan(v):
                        ax.text(j, i, f"{v:.0f}" if row == 0 else f"{v:.2f}", ha="center", va="center", fontsize=7,
                                color=cell_text_colour(im, v))
            fig.colorbar(im, ax=ax, fraction=0.046)
    if title:
        fig.suptitle(title, fontsize=11)
    save(fig, out, top=0.92 if title else 1.0)


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
