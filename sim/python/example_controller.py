#!/usr/bin/python3
"""A controller of your own against the cell (docs/python.md): image-based visual servoing
written in numpy, v = -lambda L+ (s - s*), with the interaction matrix at s* and a constant
depth, driven through cellsim.ServoEnv (the Gymnasium API's shape).

    PYTHONPATH=build/python /usr/bin/python3 sim/python/example_controller.py [SCENARIO] [--gain G]
"""
import argparse
import os
import sys

import numpy as np

import cellsim


def interaction_matrix(x, y, z):
    """The point feature's interaction matrix (Chaumette & Hutchinson), one 2 x 6 block per point."""
    L = np.zeros((2 * len(x), 6))
    L[0::2] = np.stack([-1 / z, 0 * x, x / z, x * y, -(1 + x * x), y], axis=1)
    L[1::2] = np.stack([0 * x, -1 / z, y / z, 1 + y * y, -x * y, -x], axis=1)
    return L


def proportional_controller(gain, depth):
    def control(features):
        # one row per pattern id: (x, y, x*, y*, seen); the ids matched in this frame
        x, y, xs, ys, _ = features[features[:, 4] > 0].T
        error = np.stack([x - xs, y - ys], axis=1).reshape(-1)
        return -gain * np.linalg.pinv(interaction_matrix(xs, ys, np.full_like(xs, depth))) @ error
    return control


def run(env, control, seed=None):
    # no seed: the scenario's own initial pose (a seed draws one as a campaign does)
    obs, info = env.reset(seed=seed, options=None if seed is not None else {"initial_pose": "initial"})
    total = 0.0
    while True:
        obs, reward, terminated, truncated, info = env.step(control(obs))
        total += reward
        if terminated or truncated:
            return info, total


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser()
    ap.add_argument("scenario", nargs="?", default=os.path.join(here, "..", "scenarios", "plane.yaml"))
    ap.add_argument("--gain", type=float, default=1.0)
    ap.add_argument("--depth", type=float, default=0.9, help="the constant depth of the interaction matrix (m)")
    ap.add_argument("--max-steps", type=int, default=300)
    args = ap.parse_args()
    env = cellsim.ServoEnv(cellsim.Scenario(args.scenario), max_steps=args.max_steps)
    info, total = run(env, proportional_controller(args.gain, args.depth))
    print(f"{info['reason']} after {info['steps']} steps: pose error {1e3 * info['translation_error_m']:.2f} mm, "
          f"{info['rotation_error_deg']:.3f} deg; return {total:.3f}")
    return 0 if info["reason"].startswith("converged") else 1


if __name__ == "__main__":
    sys.exit(main())
