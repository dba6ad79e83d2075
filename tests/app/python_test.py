"""The Python module end to end, as a Python user drives conesim (tests/CMakeLists.txt runs it
with Debian's python3 and the module on PYTHONPATH): the example pure-pursuit completes
autocross, a run repeats to the bit from its seed, bad input is a ValueError naming the key,
a NaN command and an early close() end the run with a DNF saying so and write its folder; the
same class as the driver of a `conesim run` (the Python driver plug-in) gives the lock-step
run's metrics, and an exception in it ends the run with a DNF naming the plug-in. Raw sensor data
(observe=): the arrays have their documented shapes and types, the LiDAR's labelled points lie
on the true cones and its other points on the ground, a camera image is not blank, the IMU's yaw
rate is the car's, and the labels are there only when asked for. A Python class as the SLAM of
a `conesim run` drives autocross and is scored as a lane; an exception in it is a DNF naming it.
usage: python_test.py SOURCE_DIR CONESIM_BINARY PYTHON_PLUGIN"""
import csv
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
# the example SLAM on autocross (seed 1, cone sensor): measured map RMSE 0.60 m (unaligned) and
# correct associations 0.999; a baseline, so the bounds only catch a broken lane (the C++
# example SLAM's test has the same)
SLAM_MAP_RMSE_M, SLAM_DA_CORRECT = 1.0, 0.95


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
def conesim_run(out, class_file, cls, kind="driver", scenario_set=()):
    spec = "{plugin: %s, config: {file: %s, class: %s}}" % (python_plugin, class_file, cls)
    extra = [a for value in scenario_set for a in ("--set", value)]
    # the conesim binary carries its own sanitizer run-time (a sanitizer build): not the one
    # preloaded into this interpreter
    run_env = {k: v for k, v in os.environ.items() if k != "LD_PRELOAD"}
    return subprocess.run([conesim_bin, "run", "autocross", "--no-plot", "--out", out, *extra,
                           "--set", "autonomy.%s=%s" % (kind, spec)], capture_output=True, text=True,
                          env=run_env)


def broken_class_dnf(name, source_text, kind, scenario_set=()):
    """The run's exit status and DNF reason with a class (named Broken) that raises."""
    path = os.path.join(work, name + ".py")
    with open(path, "w") as f:
        f.write(source_text)
    run = conesim_run(os.path.join(work, name), path, "Broken", kind, scenario_set)
    return run.returncode, json.load(open(os.path.join(work, name, "metrics.json")))["dnf_reason"]

run = conesim_run(os.path.join(work, "class"), os.path.join(source, "examples/python_driver.py"), "PurePursuit")
check("class drives conesim run", run.returncode == 0, run.stdout + run.stderr)
in_run = json.load(open(os.path.join(work, "class/metrics.json")))
timing = ("wall_time_s", "real_time_factor", "autonomy")
same = {k: v for k, v in in_run.items() if k not in timing} == {k: v for k, v in metrics.items() if k not in timing}
check("class in conesim run gives the lock-step metrics", same, (in_run["final_time_s"], metrics["final_time_s"]))
check("metrics name the Python driver", in_run["autonomy"]["driver"] == "plugin:python", in_run.get("autonomy"))

# an exception in the class ends the run with a DNF naming the plug-in and the exception
status, reason = broken_class_dnf(
    "broken", "class Broken:\n    def __init__(self, run, options):\n        self.n = 0\n"
    "    def update(self, obs):\n        self.n += 1\n"
    "        if self.n > 30:\n            raise KeyError('no such cone')\n        return (0.0, 1.0)\n", "driver")
check("exception in the class is a DNF", status == 1 and reason.startswith("driver plug-in 'python'")
      and "KeyError" in reason and "no such cone" in reason, reason)

# raw sensor data, with the LiDAR's labels asked for: the acceleration straight for 3 s
sim = conesim.Sim("acceleration", seed=2, set={"driver.check_drivable": False}, out=os.path.join(work, "raw"),
                  observe=["lidar", "camera", "imu", "wheels", "steering"], lidar_labels=True)
obs, poses, sweeps, images = sim.observation, [], [], []
while not obs["done"] and obs["t_s"] < 4.0:
    poses.append((obs["t_s"], *obs["pose"]))
    sweeps += obs["lidar"]
    images += obs["camera"]
    last = obs
    obs = sim.step((0.0, 3.0))
tick_s = obs["t_s"] - last["t_s"]  # the scenario's driver period; the IMU samples at 250 Hz
sim.close()
sweep = sweeps[-1]
check("lidar arrays", sweep["points"].dtype == np.float32 and sweep["points"].ndim == 2
      and sweep["points"].shape[1] == 6 and sweep["labels_truth"].dtype == np.int32
      and sweep["labels_truth"].shape == (len(sweep["points"]),) and len(sweep["points"]) > 1000,
      (sweep["points"].shape, sweep["labels_truth"].shape))
check("a sweep every 0.1 s", 30 <= len(sweeps) <= 40, len(sweeps))
check("labels marked as ground truth", last["ground_truth"] == ["lidar.labels_truth"], last["ground_truth"])
check("rings and times", set(np.unique(sweep["points"][:, 4])) <= set(range(16))
      and 0.0 <= sweep["points"][:, 5].min() and sweep["points"][:, 5].max() < 0.1)

# every point into the track frame at its firing time (the true pose, interpolated between
# ticks; slam: none gives the driver the truth), against the true cones of track.csv
cones = {int(r["id"]): (float(r["x"]), float(r["y"]), r["tag"])
         for r in csv.DictReader(open(os.path.join(work, "raw/track.csv"))) if r["tag"] != "car_start"}
t_tick, x_tick, y_tick, yaw_tick = (np.array(c) for c in zip(*poses))
def quaternion_rotate(q, v):
    w, u = q[0], np.asarray(q[1:])
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)
near_cone, on_ground = [], []
for sw in sweeps[5:]:
    p = sw["points"].astype(float)
    mount = sw["sensor_in_vehicle"]
    v = quaternion_rotate(mount["quaternion_wxyz"], p[:, :3]) + mount["position_m"]
    t = sw["stamp_s"] + p[:, 5]
    x, y, yaw = (np.interp(t, t_tick, a) for a in (x_tick, y_tick, yaw_tick))
    wx = x + np.cos(yaw) * v[:, 0] - np.sin(yaw) * v[:, 1]
    wy = y + np.sin(yaw) * v[:, 0] + np.cos(yaw) * v[:, 1]
    labels = sw["labels_truth"]
    for i in np.flatnonzero(labels >= 0):
        cx, cy, tag = cones[int(labels[i])]
        radius = 0.5 * (0.285 if tag == "big_orange" else 0.228)
        near_cone.append(math.hypot(wx[i] - cx, wy[i] - cy) - radius)
    ground = (labels < 0) & (np.hypot(v[:, 0], v[:, 1]) < 8.0)
    on_ground += list(np.abs(v[ground, 2]))
near_cone, on_ground = np.array(near_cone), np.array(on_ground)
# range noise 0.03 m (3 sigma 0.09 m) and the car's pitch (a few tenths of a degree)
check("labelled points on their true cones", len(near_cone) > 1000 and np.mean(near_cone < 0.1) > 0.99
      and np.median(near_cone) < 0.0, (len(near_cone), np.mean(near_cone < 0.1), np.median(near_cone)))
check("other points on the ground", len(on_ground) > 1000 and np.percentile(on_ground, 99) < 0.12,
      (len(on_ground), np.percentile(on_ground, 99) if len(on_ground) else None))

image = images[-1]
k = image["intrinsics"]
check("camera arrays", image["left"].dtype == np.uint8 and image["left"].shape == (k["height_px"], k["width_px"], 3)
      and image["right"].shape == image["left"].shape and image["K"][0, 0] == k["fx"] and image["baseline_m"] > 0.0,
      (image["left"].shape, k))
check("camera image not blank", image["left"].std() > 10.0 and not np.array_equal(image["left"], image["right"]),
      image["left"].std())
check("a camera frame every 0.1 s", 30 <= len(images) <= 40, len(images))
imu = last["imu"]
check("imu arrays", imu["gyro_rps"].shape == (len(imu["t_s"]), 3) and imu["accel_mps2"].shape == imu["gyro_rps"].shape
      and abs(len(imu["t_s"]) - 250.0 * tick_s) <= 1.0 and last["wheels"]["omega_rps"].shape == (len(last["wheels"]["t_s"]), 4)
      and last["steering"]["steer_rad"].shape == last["steering"]["t_s"].shape,
      (imu["gyro_rps"].shape, last["wheels"]["omega_rps"].shape))
check("imu specific force: gravity and the push", abs(imu["accel_mps2"][:, 2].mean() - 9.81) < 0.3
      and 1.5 < imu["accel_mps2"][:, 0].mean() < 4.5, imu["accel_mps2"].mean(axis=0))

# the car's own sensors while it turns, the LiDAR without labels
sys.path.insert(0, os.path.join(source, "examples"))
import python_driver  # noqa: E402
sim = conesim.Sim("autocross", out=os.path.join(work, "turning"), observe=["imu", "wheels", "steering", "lidar"])
obs = sim.observation
start, state = obs["pose"].copy(), {"odometer_m": 0.0, "finished": False}
gyro, truth, wheel_ratio, steer_pairs, labelled = [], [], [], [], False
while not obs["done"] and obs["t_s"] < 25.0:
    command = python_driver.drive(obs, start, state)
    previous = obs
    obs = sim.step(command)
    labelled = labelled or any("labels_truth" in sw for sw in obs["lidar"]) or obs["ground_truth"] != []
    if len(obs["imu"]["t_s"]):
        gyro.append(obs["imu"]["gyro_rps"][-1, 2])
        truth.append(obs["yaw_rate_rps"])
    if len(obs["wheels"]["t_s"]):
        wheel_ratio.append((obs["speed_mps"], obs["wheels"]["omega_rps"][:, 2:].mean()))
    if len(obs["steering"]["t_s"]):
        steer_pairs.append((previous["t_s"], command[0], obs["steering"]["steer_rad"][-1]))
sim.close()
gyro, truth = np.array(gyro), np.array(truth)
# gyro white noise 1.3e-3 rad/s per sample, turn-on bias 1e-3, the newest sample up to 4 ms
# before the tick (yaw accelerations of ~2 rad/s^2): 0.02 rad/s is several times all of them
check("imu yaw rate is the car's", np.ptp(truth) > 0.3 and np.sqrt(np.mean((gyro - truth) ** 2)) < 0.02,
      (np.ptp(truth), np.sqrt(np.mean((gyro - truth) ** 2))))
# one sample is quantised to a tooth (48 a turn) per 10 ms, so over the run: the distance the
# rear wheels roll (0.23 m radius) is the distance driven, within their slip
speeds = np.array(wheel_ratio)
radius = speeds[:, 0].sum() / speeds[:, 1].sum()
check("wheel speeds are the car's", speeds[:, 0].max() > 3.0 and abs(radius - 0.23) < 0.01, radius)
steer = np.array([p[1:] for p in steer_pairs])
check("steering sensor follows the steering", np.ptp(steer[:, 0]) > 0.1
      and np.corrcoef(steer[:, 0], steer[:, 1])[0, 1] > 0.9, np.corrcoef(steer[:, 0], steer[:, 1])[0, 1])
check("no labels unless asked", not labelled)
try:
    conesim.Sim("autocross", observe=["radar"], out=os.path.join(work, "bad2"))
    check("unknown observe refused", False, "no error")
except ValueError as e:
    check("unknown observe refused", "observe" in str(e) and "radar" in str(e), e)

# a Python class as the SLAM of a `conesim run`: a lane like any back-end, driving autocross
cone_sensor = ["perception=cone_sensor"]
run = conesim_run(os.path.join(work, "slam"), os.path.join(source, "examples/python_slam.py"), "NearestNeighbourSlam",
                  "slam", cone_sensor)
slam_metrics = json.load(open(os.path.join(work, "slam/metrics.json")))
# the example is a baseline, not a SLAM to race on: its map is 0.4-0.7 m off and its trajectory
# 0.5-1.6 m, and whether the reference driver gets round the lap on that is chance (seeds 1-7:
# 4 of 7 laps completed, most with cones hit; 5 of 7 with the driver before its roll-out model
# was mended, seed 1 among them). What the plug-in promises: the driver drives on the class's
# estimate until the run ends with a verdict, a completed lap or a DNF that says where
dnf = slam_metrics.get("dnf_reason") or ""
check("Python SLAM drives autocross", slam_metrics["slam_driving"] == "plugin:python"
      and (slam_metrics["completed"] or (" at (" in dnf and "plug-in" not in dnf)),
      run.stdout[-2000:] + run.stderr[-2000:])
lane = slam_metrics["slam"].get("plugin:python", {})
check("Python SLAM scored as a lane", slam_metrics["slam_driving"] == "plugin:python" and lane.get("role") == "drive"
      and lane.get("map_rmse_m") is not None and lane["map_rmse_m"] < SLAM_MAP_RMSE_M
      and lane.get("da_correct_fraction") is not None and lane["da_correct_fraction"] > SLAM_DA_CORRECT,
      {k: lane.get(k) for k in ("map_rmse_m", "ate_rmse_m", "da_correct_fraction")})
status, reason = broken_class_dnf(
    "broken_slam", "class Broken:\n    def __init__(self, run, options):\n        self.n, self.pose = 0, run['start_pose']\n"
    "    def reset(self, pose, t_s, prior):\n        self.pose = pose\n"
    "    def process(self, inp):\n        self.n += 1\n"
    "        if self.n > 20:\n            raise ValueError('map lost')\n"
    "    def estimate(self):\n        return {'pose': self.pose}\n", "slam", cone_sensor)
check("exception in the SLAM class is a DNF", status == 1 and reason.startswith("slam plug-in 'python'")
      and "threw in process" in reason and "map lost" in reason, reason)

print(f"{len(failures)} failed")
sys.exit(1 if failures else 0)
