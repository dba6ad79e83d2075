"""The Python module end to end, as a Python user drives conesim (tests/CMakeLists.txt runs it
with Debian's python3 and the module on PYTHONPATH): the example pure-pursuit completes
autocross, a run repeats to the bit from its seed, bad input is a ValueError naming the key,
a NaN command and an early close() end the run with a DNF saying so and write its folder; the
same class as the driver of a `conesim run` (the Python driver plug-in) gives the lock-step
run's metrics, and an exception in it ends the run with a DNF naming the plug-in.
usage: python_test.py SOURCE_DIR CONESIM_BINARY PYTHON_DRIVER_PLUGIN"""
import json
import math
import os
import subprocess
import sys
import tempfile

import conesim
import numpy as np

source, conesim_bin, python_plugin = sys.argv[1:4]
failures = []


def check(name, ok, detail=""):
    print(("ok   " if ok else "FAIL ") + name + ("" if ok else ": " + str(detail)))
    if not ok:
        failures.append(name)


work = tempfile.mkdtemp()
env = dict(os.environ)

# the example completes autocross clean, through its own command line
example = subprocess.run([sys.executable, os.path.join(source, "examples/python_driver.py"), "autocross",
                          "--out", os.path.join(work, "example")], capture_output=True, text=True, env=env)
check("example exits 0", example.returncode == 0, example.stdout + example.stderr)
metrics = json.load(open(os.path.join(work, "example/metrics.json")))
check("example completed", metrics["completed"] and metrics["penalties"]["cones_hit"] == 0, metrics["dnf_reason"])

# lock-step: numpy observations, the referee live, the same run from the same seed
def straight_run(out):
    sim = conesim.Sim("acceleration", seed=5, set={"driver.check_drivable": False}, out=out)
    obs = sim.observation
    shapes = (obs["cones"].shape[1] == 2, obs["pose"].shape == (3,), obs["cone_classes"].dtype == np.int32)
    ticks = 0
    while not obs["done"]:
        # 10 m/s to 3 m past the finish line (75 m), then brake to a stop in the braking zone
        past = obs["pose"][0] > 78.0
        obs = sim.step((0.0, -8.0 if past else (3.0 if obs["speed_mps"] < 10.0 else 0.0),
                        past and obs["speed_mps"] < 0.2))
        ticks += 1
    return sim, shapes, ticks

sim_a, shapes, ticks = straight_run(os.path.join(work, "a"))
check("observation arrays", all(shapes), shapes)
check("20 Hz ticks", ticks > 20 * 5, ticks)
check("referee live and final", sim_a.referee["laps"] == 1 and sim_a.referee["completed"], sim_a.referee)
sim_b, _, _ = straight_run(os.path.join(work, "b"))
strip = lambda m: {k: v for k, v in m.items() if k not in ("wall_time_s", "real_time_factor")}
check("same seed, same metrics", strip(sim_a.metrics()) == strip(sim_b.metrics()))
check("run folder written", os.path.exists(os.path.join(work, "a/metrics.json")))

# bad input: a ValueError naming the key, nothing written
try:
    conesim.Sim("autocross", set={"driver.explore_speed_mps": "fast"}, out=os.path.join(work, "bad"))
    check("bad --set value refused", False, "no error")
except ValueError as e:
    check("bad --set value refused", "driver.explore_speed_mps" in str(e), e)
check("bad input writes nothing", not os.path.exists(os.path.join(work, "bad")))

# a NaN command ends the run with a DNF naming the Python driver
sim = conesim.Sim("acceleration", out=os.path.join(work, "nan"))
obs = sim.step((0.0, 1.0))
while not obs["done"]:
    obs = sim.step((float("nan") if obs["t_s"] > 2.0 else 0.0, 1.0))
check("NaN command is a DNF", "the Python driver returned a number that is not finite as steer_rad"
      in sim.metrics()["dnf_reason"], sim.metrics()["dnf_reason"])

# closing early ends the run as a DNF and writes its folder
sim = conesim.Sim("autocross", out=os.path.join(work, "closed"))
for _ in range(40):
    sim.step((0.0, 1.0))
sim.close()
closed = json.load(open(os.path.join(work, "closed/metrics.json")))
check("close() early is a DNF", not closed["completed"] and "closed the simulation" in closed["dnf_reason"],
      closed["dnf_reason"])

# the example's class as the driver of a normal `conesim run`: the same run as in lock-step
def conesim_run(out, driver_file, cls):
    spec = "{plugin: %s, config: {file: %s, class: %s}}" % (python_plugin, driver_file, cls)
    return subprocess.run([conesim_bin, "run", "autocross", "--no-plot", "--out", out,
                           "--set", "autonomy.driver=" + spec], capture_output=True, text=True)

run = conesim_run(os.path.join(work, "class"), os.path.join(source, "examples/python_driver.py"), "PurePursuit")
check("class drives conesim run", run.returncode == 0, run.stdout + run.stderr)
in_run = json.load(open(os.path.join(work, "class/metrics.json")))
timing = ("wall_time_s", "real_time_factor", "autonomy")
same = {k: v for k, v in in_run.items() if k not in timing} == {k: v for k, v in metrics.items() if k not in timing}
check("class in conesim run gives the lock-step metrics", same, (in_run["final_time_s"], metrics["final_time_s"]))
check("metrics name the Python driver", in_run["autonomy"]["driver"] == "plugin:python", in_run.get("autonomy"))

# an exception in the class ends the run with a DNF naming the plug-in and the exception
broken = os.path.join(work, "broken.py")
with open(broken, "w") as f:
    f.write("class Broken:\n    def __init__(self, run, options):\n        self.n = 0\n"
            "    def update(self, obs):\n        self.n += 1\n"
            "        if self.n > 30:\n            raise KeyError('no such cone')\n        return (0.0, 1.0)\n")
run = conesim_run(os.path.join(work, "broken"), broken, "Broken")
reason = json.load(open(os.path.join(work, "broken/metrics.json")))["dnf_reason"]
check("exception in the class is a DNF", run.returncode == 1 and reason.startswith("driver plug-in 'python'")
      and "KeyError" in reason and "no such cone" in reason, reason)

print(f"{len(failures)} failed")
sys.exit(1 if failures else 0)
