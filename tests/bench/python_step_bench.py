"""How fast a Python driver can run conesim in lock-step: trackdrive with the cone sensor and
the example pure-pursuit (examples/python_driver.py: a few NumPy operations per tick) at the
scenario's 20 Hz, for up to 60 s of sim time; prints the real-time factor of each of three
runs and their median (docs/sdk.md).

    ./conesim python tests/bench/python_step_bench.py                  # cones only
    ./conesim python tests/bench/python_step_bench.py --observe lidar  # and every LiDAR sweep
"""
import argparse
import os
import statistics
import sys
import tempfile
import time

import conesim

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../examples"))
import python_driver  # noqa: E402

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--observe", default="", help="raw data in each observation: lidar,camera,imu,...")
parser.add_argument("--lidar-labels", action="store_true", help="the LiDAR points' true cone ids too")
args = parser.parse_args()
observe = [k for k in args.observe.split(",") if k]

factors = []
for run in range(3):
    sim = conesim.Sim("trackdrive", seed=1, set={"perception": "cone_sensor"},
                      out=tempfile.mkdtemp(), observe=observe, lidar_labels=args.lidar_labels)
    obs = sim.observation
    pose, state = obs["pose"].copy(), {"odometer_m": 0.0, "finished": False}
    points = 0
    start = time.perf_counter()
    while not obs["done"] and obs["t_s"] < 60.0:
        obs = sim.step(python_driver.drive(obs, pose, state))
        points += sum(len(sweep["points"]) for sweep in obs.get("lidar", []))
    wall = time.perf_counter() - start
    sim.close()
    factors.append(obs["t_s"] / wall)
    extra = f", {points / obs['t_s']:.0f} LiDAR points per sim second" if points else ""
    print(f"run {run + 1}: {obs['t_s']:.1f} s sim in {wall:.2f} s wall: {factors[-1]:.0f}x real time{extra}")
print(f"median: {statistics.median(factors):.0f}x real time")
