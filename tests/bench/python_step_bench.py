"""How fast a Python driver can run conesim in lock-step: trackdrive with the cone sensor and
a trivial driver (a fixed gentle command) at the scenario's 20 Hz, for 60 s of sim time;
prints the real-time factor of each of three runs and their median (docs/sdk.md).

    ./conesim python tests/bench/python_step_bench.py
"""
import statistics
import tempfile
import time

import conesim

factors = []
for run in range(3):
    sim = conesim.Sim("trackdrive", seed=1, set={"perception": "cone_sensor"},
                      out=tempfile.mkdtemp())
    obs = sim.observation
    start = time.perf_counter()
    while not obs["done"] and obs["t_s"] < 60.0:
        obs = sim.step((0.05, 0.5 if obs["speed_mps"] < 3.0 else 0.0))
    wall = time.perf_counter() - start
    sim.close()
    factors.append(obs["t_s"] / wall)
    print(f"run {run + 1}: {obs['t_s']:.1f} s sim in {wall:.2f} s wall: {factors[-1]:.0f}x real time")
print(f"median: {statistics.median(factors):.0f}x real time")
