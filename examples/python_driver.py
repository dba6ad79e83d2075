#!/usr/bin/env python3
"""A pure-pursuit driver in Python, run in lock-step with conesim (docs/sdk.md, "Python").

    ./conesim python examples/python_driver.py [scenario] [--seed N] [--out DIR]
    PYTHONPATH=build/python python3 examples/python_driver.py autocross

Each driver tick it steers for the middle of the gap between the nearest blue (left) and yellow
(right) cones ahead, at a look-ahead that grows with speed, holds a speed the path's curvature
allows, and stops once it is back past the start after a lap. Prints the referee's verdict and
exits 0 when the run completed clean (as `conesim run` does when its pass criteria hold).
"""
import argparse
import math
import os
import sys

try:
    import conesim
except ImportError:  # the module as `./conesim test` builds it, beside this repository
    here = os.path.dirname(os.path.abspath(__file__))
    build = os.environ.get("CONESIM_BUILD_DIR", os.path.join(here, "..", "build"))
    sys.path.insert(0, os.path.join(build, "python"))
    import conesim

import numpy as np

MAX_SPEED_MPS, LATERAL_ACCEL_MPS2, WHEELBASE_M, MAX_STEER_RAD = 6.0, 5.0, 1.53, 0.6


def target_point(cones, classes, lookahead_m):
    """The middle of the gap ahead nearest the look-ahead distance, in the vehicle frame."""
    ahead = (cones[:, 0] > -0.5) & (np.hypot(cones[:, 0], cones[:, 1]) < 14.0)
    left = cones[ahead & ((classes == conesim.BLUE) | ((classes == conesim.ORANGE_BIG) & (cones[:, 1] > 0)))]
    right = cones[ahead & ((classes == conesim.YELLOW) | ((classes == conesim.ORANGE_BIG) & (cones[:, 1] < 0)))]
    if len(left) and len(right):
        # each left cone with its nearest right cone, if they face each other across the track
        gaps = np.linalg.norm(left[:, None, :] - right[None, :, :], axis=2)
        nearest = gaps.argmin(axis=1)
        paired = gaps[np.arange(len(left)), nearest] < 6.5
        points = 0.5 * (left[paired] + right[nearest[paired]])
    else:  # one side only: half a track width from it
        points = np.vstack([left - [0.0, 1.5], right + [0.0, 1.5]])
    points = points[points[:, 0] > 1.0] if len(points) else points
    if not len(points):
        return np.array([lookahead_m, 0.0])
    return points[np.abs(np.hypot(points[:, 0], points[:, 1]) - lookahead_m).argmin()]


def drive(obs, start, state):
    """The command for one tick: (steer_rad, accel_mps2, hold_stopped)."""
    v = obs["speed_mps"]
    state["odometer_m"] += abs(v) * 0.05
    # back past the start line after a lap: brake to a stop
    dx, dy = obs["pose"][:2] - start[:2]
    along = dx * math.cos(start[2]) + dy * math.sin(start[2])
    if state["odometer_m"] > 60.0 and 3.3 < along < 15.0 and math.hypot(dx, dy) < 15.0:
        state["finished"] = True
    if state["finished"]:
        return (0.0, -6.0, False) if abs(v) > 0.3 else (0.0, 0.0, True)
    lookahead = max(3.5, 0.5 * v)
    x, y = target_point(obs["cones"], obs["cone_classes"], lookahead)
    curvature = 2.0 * math.sin(math.atan2(y, x)) / max(1.0, math.hypot(x, y))
    steer = max(-MAX_STEER_RAD, min(MAX_STEER_RAD, math.atan(WHEELBASE_M * curvature)))
    speed = min(MAX_SPEED_MPS, math.sqrt(LATERAL_ACCEL_MPS2 / max(abs(curvature), 1e-3)))
    return steer, max(-6.0, min(4.0, 2.0 * (speed - v))), False


class PurePursuit:
    """The same driver as a class, for a normal `conesim run` (docs/sdk.md, "Python"):

        ./conesim run autocross --set 'autonomy.driver={plugin: build/python/libconesim_python_plugin.so,
            config: {file: examples/python_driver.py, class: PurePursuit}}'
    """

    def __init__(self, run, options):
        self.start = None
        self.state = {"odometer_m": 0.0, "finished": False}

    def update(self, obs):
        if self.start is None:
            self.start = obs["pose"].copy()
        return drive(obs, self.start, self.state)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", nargs="?", default="autocross")
    parser.add_argument("--seed", type=int)
    parser.add_argument("--out", default="")
    args = parser.parse_args()
    sim = conesim.Sim(args.scenario, seed=args.seed, out=args.out)
    obs = sim.observation
    start, state = obs["pose"].copy(), {"odometer_m": 0.0, "finished": False}
    while not obs["done"]:
        obs = sim.step(drive(obs, start, state))
    referee = sim.referee
    print(f"{args.scenario}: {'completed' if referee['completed'] else 'DNF ' + referee['dnf_reason']}, "
          f"{referee['final_time_s']:.3f} s, {referee['cones_hit']} cones hit, "
          f"{referee['off_course']} off-course; {sim.run_dir}")
    return 0 if sim.metrics()["passed"] else 1


if __name__ == "__main__":
    sys.exit(main())
