#!/usr/bin/python3
"""Draws the paper's Fig. 5 from three experiment folders of the fig5 scenario, one per model
(L(s*, Z-hat), L(s*, Z*), L(s, Z)), in the paper's layout, one column per model:
  first row   a) the desired configuration (camera blue, projector red, the spots black), b) the
              initial camera against the desired one, close up (the move is a few centimetres
              in a metre-wide cell), c) the initial (red dots) and desired (circles) image points;
  second row  d-f) the norm of the task function vs time;
  third row   g-i) the camera velocities vs time: linear (m/s, left axis, solid) and angular
              (rad/s, right axis, dashed).
Usage: plot_fig5.py OUT.png DIR_CONSTANT_DEPTH DIR_DESIRED DIR_CURRENT [--title TITLE].
Needs Debian's python3-matplotlib (bin/setup)."""
import argparse
import csv
import json
import os
import sys

from plot_common import plt, save

MODELS = ("L(s*, Z-hat*)", "L(s*, Z*)", "L(s, Z)")


def read_trace(directory):
    path = os.path.join(directory, "trace.csv")
    try:
        with open(path) as f:
            rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
    except OSError as e:
        sys.exit(f"plot_fig5: {path}: {e.strerror}")
    if not rows:
        sys.exit(f"plot_fig5: {path} has no iterations")
    return {k: [float(r[k]) for r in rows] for k in ("t", "vx", "vy", "vz", "wx", "wy", "wz", "error_norm")}


def read_json(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        sys.exit(f"plot_fig5: {path}: {e}")


def first_features(directory):
    path = os.path.join(directory, "features.jsonl")
    try:
        with open(path) as f:
            return json.loads(f.readline())["points"]
    except (OSError, ValueError, KeyError) as e:
        sys.exit(f"plot_fig5: {path}: {e}")


def draw_frame(ax, T, colour, size=0.08, label=None):
    """A camera or projector: its centre, its optical axis and a small image rectangle."""
    o = [T[i][3] for i in range(3)]
    col = lambda j: [T[i][j] for i in range(3)]  # noqa: E731
    x, y, z = col(0), col(1), col(2)
    corners = []
    for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1), (-1, -1)):
        corners.append([o[i] + size * (z[i] + 0.6 * sx * x[i] + 0.45 * sy * y[i]) for i in range(3)])
    for c in corners[:4]:
        ax.plot([o[0], c[0]], [o[1], c[1]], [o[2], c[2]], color=colour, lw=0.8)
    ax.plot(*zip(*corners), color=colour, lw=1.2, label=label)
    ax.plot([o[0], o[0] + 2.5 * size * z[0]], [o[1], o[1] + 2.5 * size * z[1]], [o[2], o[2] + 2.5 * size * z[2]],
            color=colour, lw=0.6, ls="--")


def fit_cube(ax, pts, margin):
    """Equal axes (metres) around the points, `margin` beyond them, labelled."""
    lo = [min(q[i] for q in pts) for i in range(3)]
    hi = [max(q[i] for q in pts) for i in range(3)]
    half = max(h - l for l, h in zip(lo, hi)) / 2 + margin
    for i, setter in enumerate((ax.set_xlim, ax.set_ylim, ax.set_zlim)):
        mid = (lo[i] + hi[i]) / 2
        setter(mid - half, mid + half)
    ax.set_xlabel("x (m)", fontsize=7)
    ax.set_ylabel("y (m)", fontsize=7)
    ax.set_zlabel("z (m)", fontsize=7)


def draw_scene(ax, scene, camera_key, title):
    draw_frame(ax, scene["projector"], "tab:red", 0.12, "projector")
    draw_frame(ax, scene[camera_key], "tab:blue", 0.08, "camera")
    p = scene["projector"]
    for s in scene["spots"]:
        x, y, z = s["point_w"]
        ax.scatter([x], [y], [z], color="k", s=12)
        ax.plot([p[0][3], x], [p[1][3], y], [p[2][3], z], color="tab:red", lw=0.3, alpha=0.5)
    pts = [[scene[k][i][3] for i in range(3)] for k in ("projector", camera_key)] + [s["point_w"] for s in scene["spots"]]
    fit_cube(ax, pts, 0.05)
    ax.tick_params(labelsize=6)
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=6, loc="upper left")


def moved(a, b):
    """Translation (mm) and rotation (deg) between two 4 x 4 poses."""
    import math
    t = math.sqrt(sum((a[i][3] - b[i][3]) ** 2 for i in range(3))) * 1000
    trace = sum(a[0][k] * b[0][k] + a[1][k] * b[1][k] + a[2][k] * b[2][k] for k in range(3))
    return t, math.degrees(math.acos(max(-1.0, min(1.0, (trace - 1) / 2))))


def draw_move(ax, scene):
    """The initial camera (blue) against the desired one (grey), their rays to the spots, close up."""
    draw_frame(ax, scene["camera_desired"], "0.55", 0.03, "desired camera")
    draw_frame(ax, scene["camera_initial"], "tab:blue", 0.03, "initial camera")
    cams = [[scene[k][i][3] for i in range(3)] for k in ("camera_desired", "camera_initial")]
    for c, colour in zip(cams, ("0.55", "tab:blue")):
        for s in scene["spots"]:
            x, y, z = s["point_w"]
            ax.plot([c[0], x], [c[1], y], [c[2], z], color=colour, lw=0.4, alpha=0.6)
    fit_cube(ax, cams, 0.06)
    t, r = moved(scene["camera_desired"], scene["camera_initial"])
    ax.tick_params(labelsize=6)
    ax.set_title(f"b) initial camera, close up: {t:.0f} mm and {r:.1f}° from the desired", fontsize=9)
    ax.legend(fontsize=6, loc="upper left")


def draw_velocities(ax, t, title):
    """Linear velocities on the left axis (m/s), angular on the right (rad/s)."""
    lines = []
    for key in ("vx", "vy", "vz"):
        lines += ax.plot(t["t"], t[key], "-", lw=1, label=key + " (m/s)")
    ax.set_ylabel("linear velocity (m/s)")
    right = ax.twinx()
    for key, colour in (("wx", "tab:red"), ("wy", "tab:purple"), ("wz", "tab:brown")):
        lines += right.plot(t["t"], t[key], "--", lw=1, color=colour, label=key + " (rad/s)")
    right.set_ylabel("angular velocity (rad/s)")
    right.tick_params(labelsize=8)
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("time (s)")
    ax.grid(True, alpha=0.3)
    return lines


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("dirs", nargs=3)
    ap.add_argument("--title", default="")
    a = ap.parse_args()
    traces = [read_trace(d) for d in a.dirs]
    scene = read_json(os.path.join(a.dirs[0], "scene.json"))
    points = first_features(a.dirs[0])

    fig = plt.figure(figsize=(14, 11))
    ax = fig.add_subplot(3, 3, 1, projection="3d")
    draw_scene(ax, scene, "camera_desired", "a) desired configuration")
    ax = fig.add_subplot(3, 3, 2, projection="3d")
    draw_move(ax, scene)
    ax = fig.add_subplot(3, 3, 3)
    ax.scatter([p["x"] for p in points], [p["y"] for p in points], color="tab:red", s=18, label="initial")
    ax.scatter([p["x_star"] for p in points], [p["y_star"] for p in points], facecolors="none", edgecolors="k", s=60,
               label="desired")
    ax.invert_yaxis()
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (normalised)")
    ax.set_ylabel("y (normalised)")
    ax.set_title("c) image points", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)

    for c, (name, t) in enumerate(zip(MODELS, traces)):
        ax = fig.add_subplot(3, 3, 4 + c)
        ax.plot(t["t"], t["error_norm"], color="k")
        ax.set_title(f"{'def'[c]}) |e| with {name}", fontsize=9)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("|e|")
        ax.grid(True, alpha=0.3)
        lines = draw_velocities(fig.add_subplot(3, 3, 7 + c), t, f"{'ghi'[c]}) camera velocities with {name}")
    # one legend for the three velocity panels, below them: inside, it hid the curves
    fig.legend(lines, [ln.get_label() for ln in lines], loc="lower center", ncol=6, fontsize=9, frameon=False)

    if a.title:
        fig.suptitle(a.title)
    save(fig, a.out, dpi=100, top=0.97, bottom=0.04)


if __name__ == "__main__":
    main()
