#!/usr/bin/python3
"""Plots an experiment's trace.csv like the paper's Fig. 4c-d / 5d-i:
velocities.png (camera velocities vs time) and error_norm.png (norm of the task function);
pose_error.png, the camera's true distance and angle to the goal (the simulator's truth: the
task function passing its test says the law is done, this says where the camera is);
with decoded features, fig4.png: the initial and desired images with their decoded ids beside
the velocities and |e|, the paper's Fig. 4 in one picture;
with an arm, occlusion.png from occlusion.csv (spots the arm hides or catches, per frame);
with the robust law, weights.png from features.jsonl (genuine and swapped matches).
Usage: plot_trace.py DIR [--title TITLE]. Needs Debian's python3-matplotlib (bin/setup)."""
import csv
import os
import re
import sys

from plot_common import dir_and_title, plt, save


# what |e| is made of, by the visual features the trace's first line names (cellsim experiment)
ERROR_UNITS = {
    "points": "|e| (normalised image coordinates)",
    "moments": "|e| (image moments: normalised coordinates, ratios, rad)",
    "surface": "|e| (n: unit vector, d: m, moments)",
    "plane": "|e| (the plane's n: unit vector, d: m)",
}


def error_label(path):
    """The y label of |e| for the visual features the trace names; points when it names none."""
    with open(path) as f:
        first = f.readline()
    m = re.search(r"visual features (\w+)", first) if first.startswith("#") else None
    return ERROR_UNITS.get(m.group(1) if m else "points", ERROR_UNITS["points"])


def read_trace(path):
    with open(path) as f:
        lines = [line for line in f if not line.startswith("#")]
    rows = list(csv.DictReader(lines))
    if not rows:
        sys.exit(f"plot_trace: {path} has no iterations")
    text = {"robot_limits"}  # the robot's reasons for limiting a step: names, not numbers
    t = {k: [r[k] if k in text else float(r[k]) for r in rows] for k in rows[0]}
    t["error_label"] = error_label(path)
    return t


def plot_occlusion(directory, title, trace=None):
    path = os.path.join(directory, "occlusion.csv")
    if not os.path.exists(path):
        return
    with open(path) as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return
    t = [float(r["t"]) for r in rows]
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    ax.plot(t, [int(r["visible"]) for r in rows], color="k", label="visible to the camera")
    ax.plot(t, [int(r["on_arm"]) for r in rows], color="tab:red", label="caught by the arm (its shadow on the object)")
    ax.plot(t, [int(r["hidden_by_arm"]) for r in rows], color="tab:orange", label="hidden from the camera by the arm")
    if trace and "decoded" in trace:
        ax.plot(trace["t"], trace["decoded"], "--", color="tab:blue", label="decoded by the servo")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("spots")
    ax.set_title(f"{title}: the arm and the pattern" if title else "the arm and the pattern")
    ax.grid(True, alpha=0.3)
    # below the axes: inside, it covered the first seconds of the curves
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, frameon=False)
    save(fig, os.path.join(directory, "occlusion.png"))


def plot_weights(directory, title):
    """weights.png from features.jsonl: the robust law's weight of the genuine matches and of
    the ones the outlier injection made wrong (issue 19), per iteration."""
    import json
    path = os.path.join(directory, "features.jsonl")
    if not os.path.exists(path):
        return
    t, good, bad, bad_max = [], [], [], []
    with open(path) as f:
        for line in f:
            j = json.loads(line)
            pts = [p for p in j.get("points", []) if p.get("weight") is not None]
            if not pts:
                continue
            g = sorted(p["weight"] for p in pts if not p.get("swapped"))
            b = sorted(p["weight"] for p in pts if p.get("swapped"))
            t.append(j["k"])
            good.append(g[len(g) // 2] if g else float("nan"))
            bad.append(b[len(b) // 2] if b else float("nan"))
            bad_max.append(b[-1] if b else float("nan"))
    if not t:
        return
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.plot(t, good, color="tab:green", label="genuine matches (median)")
    if any(v == v for v in bad):
        ax.plot(t, bad, color="tab:red", label="swapped ids (median)")
        ax.plot(t, bad_max, ":", color="tab:red", label="swapped ids (largest)")
    ax.set_xlabel("iteration")
    ax.set_ylabel("robust weight")
    ax.set_ylim(-0.05, 1.05)
    ax.set_title(f"{title}: robust weights" if title else "robust weights")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    save(fig, os.path.join(directory, "weights.png"))


def plot_fig4(directory, title, t):
    """The paper's Fig. 4 in one picture: a) the initial image, b) the desired one, each with the
    ids decoded in it (initial.png, desired.png, written by the experiment), c) the camera's
    velocities, translation and rotation on axes of their own, d) |e|."""
    images = [os.path.join(directory, n) for n in ("initial.png", "desired.png")]
    if not all(os.path.exists(p) for p in images):
        return
    fig = plt.figure(figsize=(12, 9.5))
    grid = fig.add_gridspec(3, 2, height_ratios=(1.5, 0.75, 0.75))
    for k, (path, what) in enumerate(zip(images, ("a) initial image", "b) desired image"))):
        ax = fig.add_subplot(grid[0, k])
        ax.imshow(plt.imread(path))
        ax.set_title(f"{what}, decoded ids", fontsize=10)
        ax.set_axis_off()
    for row, keys, unit in ((1, ("vx", "vy", "vz"), "m/s"), (2, ("wx", "wy", "wz"), "rad/s")):
        ax = fig.add_subplot(grid[row, 0])
        for key, colour in zip(keys, ("tab:red", "tab:green", "tab:blue")):
            ax.plot(t["t"], t[key], color=colour, label=key)
        ax.set_ylabel(f"{'translation' if unit == 'm/s' else 'rotation'} ({unit})")
        ax.grid(True, alpha=0.3)
        ax.legend(ncol=3, fontsize=8, loc="upper right")
        if row == 1:
            ax.set_title("c) camera velocities", fontsize=10)
        else:
            ax.set_xlabel("time (s)")
    ax = fig.add_subplot(grid[1:, 1])
    ax.plot(t["t"], t["error_norm"], color="k")
    ax.set_yscale("log")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(t["error_label"])
    ax.set_title("d) norm of the task function", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    if title:
        fig.suptitle(title)
    save(fig, os.path.join(directory, "fig4.png"), top=0.95 if title else 1.0)


def plot_pose_error(directory, title, t):
    """The camera's true translation (mm) and rotation (deg) to the goal per frame, log scale."""
    if "translation_error_m" not in t or "rotation_error_deg" not in t:
        return
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(6.4, 5.2), sharex=True)
    top.plot(t["t"], [1e3 * v for v in t["translation_error_m"]], color="k")
    top.set_ylabel("translation (mm)")
    bottom.plot(t["t"], t["rotation_error_deg"], color="k")
    bottom.set_ylabel("rotation (deg)")
    for ax in (top, bottom):
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
    bottom.set_xlabel("time (s)")
    what = "the camera's true pose error to the goal"
    top.set_title(f"{title}:\n{what}" if title else what, fontsize=10)
    save(fig, os.path.join(directory, "pose_error.png"))


def main():
    args = dir_and_title()
    trace = os.path.join(args.dir, "trace.csv")
    if not os.path.exists(trace):
        sys.exit(f"plot_trace: {trace} not found")
    t = read_trace(trace)

    # translation and rotation on axes of their own: m/s and rad/s are not one unit
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(6.4, 5.2), sharex=True)
    for ax, keys, unit in ((top, ("vx", "vy", "vz"), "m/s"), (bottom, ("wx", "wy", "wz"), "rad/s")):
        for key, colour in zip(keys, ("tab:red", "tab:green", "tab:blue")):
            ax.plot(t["t"], t[key], color=colour, label=key)
        ax.set_ylabel(f"{'translation' if unit == 'm/s' else 'rotation'} ({unit})")
        ax.grid(True, alpha=0.3)
        ax.legend(ncol=3, fontsize=8, loc="upper right")
    bottom.set_xlabel("time (s)")
    top.set_title(f"{args.title}: camera velocities" if args.title else "camera velocities")
    save(fig, os.path.join(args.dir, "velocities.png"))

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.plot(t["t"], t["error_norm"], color="k")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(t["error_label"])
    ax.set_yscale("log")
    ax.set_title(f"{args.title}: norm of the task function" if args.title else "norm of the task function")
    ax.grid(True, which="both", alpha=0.3)
    save(fig, os.path.join(args.dir, "error_norm.png"))
    plot_fig4(args.dir, args.title, t)
    plot_pose_error(args.dir, args.title, t)
    plot_occlusion(args.dir, args.title, t)
    plot_weights(args.dir, args.title)


if __name__ == "__main__":
    main()
