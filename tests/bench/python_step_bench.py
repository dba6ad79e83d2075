"""How fast a Python driver can run conesim in lock-step: trackdrive with the cone sensor and
the example pure-pursuit (examples/python_driver.py: a few NumPy operations per tick) at the
scenario's 20 Hz, for up to 60 s of sim time; prints the real-time factor of each of three
runs and their median (docs/sdk.md).

    ./conesim python tests/bench/python_step_bench.py
"""
import os
import statistics
import sys
import tempfile
import time

import conesim

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../examples"))
import python_driver  # noqa: E402

factors = []
for run in range(3):
    sim = conesim.Sim("trackdrive", seed=1, set={"perception": "cone_sensor"},
                      out=tempfile.mkdtemp())
    obs = sim.observation
    pose, state = obs["pose"].copy(), {"odometer_m": 0.0, "finished": False}
    start = time.perf_counter()
    while not obs["done"] and obs["t_s"] < 60.0:
        obs = sim.step(python_driver.drive(obs, pose, state))
    wall = time.perf_counter() - start
    sim.close()
    factors.append(obs["t_s"] / wall)
    print(f"run {run + 1}: {obs['t_s']:.1f} s sim in {wall:.2f} s wall: {factors[-1]:.0f}x real time")
print(f"median: {statistics.median(factors):.0f}x real time")
