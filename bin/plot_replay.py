#!/usr/bin/python3
"""Plots a replay's replay.csv (servo replay -o DIR): replay.png, the twist the recorded servo
sent and the one the replayed servo would send, per component against time, and where they
differ. Usage: plot_replay.py DIR [--title TITLE]. Needs Debian's python3-matplotlib."""
import csv
import os
import sys

from plot_common import dir_and_title, plt, save


def main():
    args = dir_and_title()
    directory, title = args.dir, args.title or "replay"
    with open(os.path.join(directory, "replay.csv")) as f:
        rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
    if not rows:
        sys.exit(f"plot_replay: {directory}/replay.csv has no twists")
    t = [float(r["t"]) for r in rows]
    fig, axes = plt.subplots(3, 1, figsize=(7.0, 8.0), sharex=True)
    colours = ["tab:red", "tab:green", "tab:blue"]
    for ax, kind, unit in ((axes[0], "v", "m/s"), (axes[1], "w", "rad/s")):
        for axis, colour in zip("xyz", colours):
            ax.plot(t, [float(r[f"rec_{kind}{axis}"]) for r in rows], "--", color=colour, alpha=0.6,
                    label=f"{kind}{axis} recorded")
            ax.plot(t, [float(r[f"{kind}{axis}"]) for r in rows], color=colour, linewidth=1, label=f"{kind}{axis} replayed")
        ax.set_ylabel(unit)
        ax.legend(fontsize=7, ncol=3)
    diff = [max(float(r["max_abs_diff"]), 1e-18) for r in rows]
    axes[2].semilogy(t, diff, color="k")
    axes[2].set_ylabel("max |replayed - recorded|")
    axes[2].set_xlabel("time (s)")
    same = sum(int(r["identical"]) for r in rows)
    axes[2].set_title(f"{same} of {len(rows)} twists identical bit for bit", fontsize=9)
    fig.suptitle(title)
    save(fig, os.path.join(directory, "replay.png"))


if __name__ == "__main__":
    main()
