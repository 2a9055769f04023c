"""What the plot scripts share (imported by them, not run): matplotlib without a display, the
DIR [--title TITLE] arguments, and saving a figure. Debian's python3-matplotlib (bin/setup)."""
import argparse
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402,F401  (the scripts take plt from here)

from cell_output import open_output  # noqa: E402


def dir_and_title():
    """The arguments DIR [--title TITLE] every folder-plotting script takes."""
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--title", default="")
    return ap.parse_args()


def save(fig, path, dpi=110, top=1.0, bottom=0.0):
    """Lays the figure out (leaving `top` of its height to the panels: a suptitle above them
    is not cut; and the panels above `bottom`: a figure legend below them is not covered) and
    writes it (under cell_output's rule: never over a file the project did not write)."""
    fig.tight_layout(rect=(0, bottom, 1, top))
    try:
        with open_output(path, "wb") as f:
            fig.savefig(f, dpi=dpi, format=os.path.splitext(path)[1].lstrip(".") or "png")
    except OSError as e:  # a full disk: one line, not a traceback
        sys.exit(f"{os.path.basename(sys.argv[0])}: {path}: cannot write the plot: {e.strerror or e}")
    plt.close(fig)
