// The Python face of ServoEnv (issue 43, item 3): Gymnasium's contract (observation_space and
// action_space with Box's interface, np_random, reset(seed=None) drawing a fresh pose, render,
// close), written in Python over the compiled engine (_ServoEnvCore) and run into the module at
// import. Gymnasium itself is not a dependency (Debian has no package); where it is importable,
// ServoEnv is a gymnasium.Env and its spaces are gymnasium's Box.
#pragma once

namespace cellsim_python {

inline constexpr const char* kGymnasiumLayer = R"py(
import numpy as _np

try:
    import gymnasium as _gym
except ImportError:
    _gym = None


class Box:
    """A box of R^n with Gymnasium's Box interface: shape, dtype, low, high, seed(), sample(),
    contains() (and `x in box`). Unbounded components are sampled from a normal distribution,
    half-bounded ones from an exponential, as Gymnasium does."""

    def __init__(self, low, high, shape, dtype):
        self.shape = tuple(int(n) for n in shape)
        self.dtype = _np.dtype(dtype)
        self.low = _np.broadcast_to(_np.asarray(low, dtype=self.dtype), self.shape).copy()
        self.high = _np.broadcast_to(_np.asarray(high, dtype=self.dtype), self.shape).copy()
        self.np_random = _np.random.default_rng()

    def seed(self, seed=None):
        self.np_random = _np.random.default_rng(seed)
        return [seed]

    def sample(self):
        low, high = self.low.astype(_np.float64), self.high.astype(_np.float64)
        if self.dtype.kind in "ui":
            return self.np_random.integers(low, high + 1, size=self.shape).astype(self.dtype)
        out = _np.empty(self.shape)
        both = _np.isfinite(low) & _np.isfinite(high)
        above = _np.isfinite(low) & ~_np.isfinite(high)
        below = ~_np.isfinite(low) & _np.isfinite(high)
        free = ~(both | above | below)
        out[both] = self.np_random.uniform(low[both], high[both])
        out[above] = low[above] + self.np_random.exponential(size=int(above.sum()))
        out[below] = high[below] - self.np_random.exponential(size=int(below.sum()))
        out[free] = self.np_random.normal(size=int(free.sum()))
        return out.astype(self.dtype)

    def contains(self, x):
        x = _np.asarray(x)
        return (x.shape == self.shape and _np.can_cast(x.dtype, self.dtype, casting="same_kind")
                and bool(_np.all(x >= self.low)) and bool(_np.all(x <= self.high)))

    __contains__ = contains

    def __repr__(self):
        return f"Box({self.low.min()}, {self.high.max()}, {self.shape}, {self.dtype})"


_Env = _gym.Env if _gym is not None else object


class ServoEnv(_Env):
    """The cell as an environment for a controller of yours, with Gymnasium's contract.

    ServoEnv(scenario, observation="features", max_steps=300, model="desired-constant-depth",
             z_hat=0.0, gain=0.5, robust="none", render_mode=None, white_frame=False, features="decoded")

    reset(seed=None, options=None) -> (obs, info): teaches at the desired pose, sends the robot
        to an initial pose and starts. A seed draws that pose as a campaign of that seed draws
        its first and reseeds np_random; without one, the pose is drawn from np_random (a fresh
        one each episode). options={"initial_pose": POSE} takes any pose Scenario.render takes
        ("initial": the scenario's own).
    step(action) -> (obs, reward, terminated, truncated, info): action is the camera twist
        (vx vy vz wx wy wz, m/s and rad/s, camera frame); reward = -|e|.
    observation "features": one row per pattern id (rows x cols of them, row-major):
        (x, y, x*, y*, seen) in normalised image coordinates, zeros and seen = 0 where the id is
        not matched this frame; "image": the H x W x 3 uint8 frame.
    render(): the last frame (H x W x 3 uint8) with render_mode="rgb_array", else None.
    white_frame=True: beside each frame the white reference frame, and the features decoded from
        their ratio (the surface's albedo divided out; the observation image stays the frame).
    features: where the matched spots come from, as cellsim campaign --features: "decoded" (the
        frame decoded), "decoded-ids" (the decoder's ids at their true positions), "resolved" or
        "ideal" (the simulator's truth, no frame: observation "features" only).
    info: see docs/python.md (error_norm, detected, decoded, ids, limited, the truth)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": None}

    def __init__(self, scenario, observation="features", max_steps=300, model="desired-constant-depth",
                 z_hat=0.0, gain=0.5, robust="none", render_mode=None, white_frame=False, features="decoded"):
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        if render_mode == "rgb_array" and features in ("ideal", "resolved"):
            raise ValueError(f"render_mode='rgb_array' needs features='decoded' or 'decoded-ids' ({features!r}: the "
                             "truth renders no frame)")
        self._core = _ServoEnvCore(scenario, observation, max_steps, model, z_hat, gain, robust, bool(white_frame),
                                   str(features))
        self.render_mode = render_mode
        self.metadata = dict(ServoEnv.metadata, render_fps=1.0 / scenario.dt)
        space = _gym.spaces.Box if _gym is not None else Box
        if observation == "features":
            rows, cols = self._core.pattern_shape
            low = _np.full((rows * cols, 5), -_np.inf)
            high = _np.full((rows * cols, 5), _np.inf)
            low[:, 4], high[:, 4] = 0.0, 1.0
            self.observation_space = space(low, high, (rows * cols, 5), _np.float64)
        else:
            self.observation_space = space(0, 255, (scenario.height, scenario.width, 3), _np.uint8)
        linear, angular = self._core.speed_limits
        limit = _np.array([linear] * 3 + [angular] * 3)
        self.action_space = space(-limit, limit, (6,), _np.float64)
        self.np_random = _np.random.default_rng()

    def reset(self, *, seed=None, options=None):
        """A new episode: (obs, info). seed: 0 .. 2**64 - 1 or None (a fresh pose from np_random);
        options: {"initial_pose": POSE} only."""
        self._open()
        if seed is not None:
            if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**64:
                raise ValueError(f"reset: seed must be None or a whole number from 0 to 2**64 - 1, got {seed!r}")
            self.np_random = _np.random.default_rng(seed)
            draw = seed
        else:
            draw = int(self.np_random.integers(0, 2**63))
        if options is not None and "initial_pose" in options:
            draw = None  # the pose is the caller's
        return self._core.reset(draw, options)

    def step(self, action):
        """One frame with your camera twist: (obs, reward, terminated, truncated, info)."""
        return self._open().step(action)

    def render(self):
        """The last frame, H x W x 3 uint8, with render_mode="rgb_array"; else None."""
        if self.render_mode != "rgb_array" or self._core is None:
            return None
        return self._core.frame()

    def _open(self):
        if self._core is None:
            raise RuntimeError("ServoEnv: closed (make a new one)")
        return self._core

    def close(self):
        """Lets the engine go; render() then gives None, reset() and step() raise."""
        self._core = None
)py";

}  // namespace cellsim_python
