#!/usr/bin/env python3
"""The 3D replay end to end (issue 16): a short LiDAR + SLAM run with --replay on a layout with a
cone in the lane (one cone hit, then a DNF on a short time limit), its replay.html opened in
headless Chromium at a time given in the URL (#t=..., which the page's own scrub code handles),
the page's state (the <pre id="state"> JSON, read with --dump-dom) checked against metrics.json
and trajectory.csv, and a screenshot checked for the car, the cones and the LiDAR points. Bad run
folders are refused with the file named and no replay.html written. A short autocross-stereo run
with --replay records camera frames: its page shows the frame of the scrubbed time with its
boxes in the corner panel (the state says which frame, its boxes, and that the image was drawn),
and `conesim view --mp4-view camera` makes its camera video; the LiDAR run's page has no panel.

usage: replay_test.py CONESIM_BINARY TEST_DATA_DIR
"""
import csv
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from app_checks import fail, failures, read_png, run  # noqa: E402

BIN = os.path.abspath(sys.argv[1])
DATA = os.path.abspath(sys.argv[2])
TRACK = os.path.join(DATA, "replay", "cone_in_the_lane.csv")
# the moment checked: after the cone hit (2.82 s), before the DNF; a trajectory row (20 Hz)
T_CHECK = 8.5
# the camera run: autocross-stereo stopped after a few seconds, checked at this time
CAMERA_LIMIT_S = 5
T_CAMERA = 4.1
def chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    print("FAIL no chromium in PATH: install Debian's chromium (debian-packages.txt; ./conesim "
          "installs it)")
    sys.exit(1)


def browser(profile, *args):
    """Headless Chromium with software WebGL (SwiftShader through ANGLE: no GPU needed)."""
    cmd = [chromium(), "--headless", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
           "--no-first-run", "--no-default-browser-check", "--hide-scrollbars",
           # a container's small /dev/shm: shared memory files go to /tmp instead
           "--disable-dev-shm-usage",
           "--user-data-dir=" + profile, "--window-size=1280,800"]
    if os.geteuid() == 0:
        cmd.append("--no-sandbox")  # Chromium refuses to run as root with its sandbox
    start = time.monotonic()
    p = subprocess.run(cmd + list(args), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                       text=True, timeout=300)
    return p, time.monotonic() - start


def page_state(html):
    m = re.search(r'<pre id="state"[^>]*>([^<]*)</pre>', html)
    if not m:
        return None
    text = m.group(1).replace("&quot;", '"').replace("&lt;", "<").replace("&gt;", ">")
    text = text.replace("&amp;", "&")
    try:
        return json.loads(text)
    except ValueError:
        return None  # the page's script stopped before it wrote its state


def main():
    top = tempfile.mkdtemp(prefix="conesim-replay-")
    try:
        check_all(top)
    finally:
        shutil.rmtree(top, ignore_errors=True)
    if failures:
        print("%d check(s) failed" % len(failures))
        sys.exit(1)
    print("replay: all checks passed")


def check_all(top):
    run_dir = os.path.join(top, "run")
    # 1: the run writes replay.bin and replay.html (it fails its pass criteria: exit 1)
    t0 = time.monotonic()
    run([BIN, "run", "trackdrive-lidar", "--track", TRACK, "--no-plot", "--replay",
         "--set", "referee.timeout_trackdrive_total_s=12", "--set", "slam.shadow=[ekf]",
         "--out", run_dir], expect=(0, 1))
    print("run: %.1f s" % (time.monotonic() - t0))
    page = os.path.join(run_dir, "replay.html")
    for name in ("replay.bin", "replay.html", "metrics.json", "trajectory.csv", "track.csv"):
        if not os.path.isfile(os.path.join(run_dir, name)):
            fail("the run wrote no " + name)
    if failures:
        return
    size_mb = os.path.getsize(page) / 1e6
    print("replay.html: %.2f MB" % size_mb)
    if not 0.9 < size_mb < 50:
        fail("replay.html is %.2f MB (three.js alone is 0.85 MB; at most 50)" % size_mb)
    leftovers = [n for n in os.listdir(run_dir) if n.startswith(".partial")]
    if leftovers:
        fail("partial files left in the run folder: %s" % leftovers)

    # 2: bad run folders: exit 2, the missing or broken file named, no replay.html
    def refused(name, folder, regex):
        p = run([BIN, "view", folder], expect=(2,))
        if not re.search(regex, p.stderr):
            fail("%s: stderr does not match /%s/: %s" % (name, regex, p.stderr.strip()[:300]))
        if os.path.exists(os.path.join(folder, "replay.html")):
            fail(name + ": a replay.html was written")
    empty = os.path.join(top, "empty")
    os.mkdir(empty)
    refused("empty folder", empty, r"empty/metrics\.json: missing")
    refused("no folder", os.path.join(top, "nothing"), r"nothing: not a folder")
    for missing in ("trajectory.csv", "track.csv"):
        partial = os.path.join(top, "no-" + missing)
        shutil.copytree(run_dir, partial)
        os.remove(os.path.join(partial, missing))
        os.remove(os.path.join(partial, "replay.html"))
        refused("no " + missing, partial, re.escape(missing))
    broken = os.path.join(top, "broken-log")
    shutil.copytree(run_dir, broken)
    os.remove(os.path.join(broken, "replay.html"))
    with open(os.path.join(broken, "replay.bin"), "r+b") as f:
        f.truncate(os.path.getsize(os.path.join(broken, "replay.bin")) - 5)
    refused("truncated replay.bin", broken, r"replay\.bin: not a replay log .* at byte \d+")
    bad_csv = os.path.join(top, "bad-trajectory")
    shutil.copytree(run_dir, bad_csv)
    os.remove(os.path.join(bad_csv, "replay.html"))
    with open(os.path.join(bad_csv, "trajectory.csv"), "a") as f:
        f.write("1e400,x\n")
    refused("bad trajectory row", bad_csv, r"trajectory\.csv:\d+: ")
    # an older replay.html stays as it was when the new one cannot be made
    with open(os.path.join(bad_csv, "replay.html"), "w") as f:
        f.write("old")
    run([BIN, "view", bad_csv], expect=(2,))
    with open(os.path.join(bad_csv, "replay.html")) as f:
        if f.read() != "old":
            fail("a failed view replaced an existing replay.html")

    # 3: `conesim view` on the good folder writes the page again
    os.remove(page)
    p = run([BIN, "view", run_dir], expect=(0,))
    if not os.path.isfile(page):
        fail("conesim view wrote no replay.html")
        return

    with open(os.path.join(run_dir, "metrics.json")) as f:
        metrics = json.load(f)
    with open(os.path.join(run_dir, "trajectory.csv")) as f:
        rows = list(csv.DictReader(f))
    row = min(rows, key=lambda r: abs(float(r["t_s"]) - T_CHECK))
    url = "file://" + page + "#t=%g&colour=label" % T_CHECK

    # 4: the page's state at the scrubbed time
    p, seconds = browser(os.path.join(top, "profile-dom"), "--virtual-time-budget=3000",
                         "--dump-dom", url)
    state = page_state(p.stdout)
    print("chromium --dump-dom: %.1f s" % seconds)
    if state is None:
        fail("no page state in the DOM (exit %d): %s" % (p.returncode, p.stderr[-600:]))
        return
    print("page state: " + json.dumps(state))
    if abs(state["t"] - T_CHECK) > 1e-6:
        fail("shown time %s, asked for %s" % (state["t"], T_CHECK))
    for key, col in (("x", "x_m"), ("y", "y_m"), ("yaw", "yaw_rad"), ("steer", "steer_rad")):
        if abs(state["pose"][key] - float(row[col])) > 2e-3:
            fail("pose.%s %s, trajectory.csv at %s s says %s" % (key, state["pose"][key],
                                                                row["t_s"], row[col]))
    for key, col in (("x", "est_x_m"), ("y", "est_y_m")):
        if abs(state["estimate"][key] - float(row[col])) > 2e-3:
            fail("estimate.%s %s, trajectory.csv says %s" % (key, state["estimate"][key], row[col]))
    want = [(e["kind"], e["t_s"]) for e in metrics["events"]]
    got = [(e["kind"], e["t_s"]) for e in state["events"]]
    if got != want or not want:
        fail("events %s, metrics.json has %s" % (got, want))
    hits = [e for e in metrics["events"] if e["kind"] == "cone_hit" and e["t_s"] <= T_CHECK]
    if state["cones_down"] != len(hits) or not hits:
        fail("%s cones down at %s s, metrics.json has %d hits by then" %
             (state["cones_down"], T_CHECK, len(hits)))
    if state["events_so_far"] != sum(1 for e in metrics["events"] if e["t_s"] <= T_CHECK):
        fail("events_so_far %s" % state["events_so_far"])
    sweep = state.get("sweep")
    if not sweep or sweep["points"] < 100 or not (T_CHECK - 1.0 <= sweep["t"] <= T_CHECK):
        fail("no LiDAR sweep of the last second shown: %s" % sweep)
    outcome = (sweep or {}).get("outcome")
    if not outcome or outcome["found"] < 1 or outcome["cones_with_points"] < outcome["found"] \
            or abs(outcome["detections_t"] - sweep["t"]) > 0.06:
        fail("no detection outcome for the shown sweep: %s" % outcome)
    for lane in ("graph", "ekf"):
        if state["maps"].get(lane, 0) < 5:
            fail("the %s map shows %s landmarks at %s s" % (lane, state["maps"].get(lane), T_CHECK))
    if state.get("load_ms") is not None:
        print("page ready %d ms after navigation (script %d ms)" % (state["load_ms"],
                                                                   state["script_ms"]))

    if state.get("camera_frame") is not None:
        fail("a run without a camera shows a camera panel: %s" % state["camera_frame"])

    # 5: a screenshot at the same moment shows the car, cones and points
    shot = os.path.join(top, "shot.png")
    p, seconds = browser(os.path.join(top, "profile-shot"), "--virtual-time-budget=3000",
                         "--screenshot=" + shot, url)
    print("chromium --screenshot: %.1f s" % seconds)
    if not os.path.isfile(shot):
        fail("no screenshot (exit %d): %s" % (p.returncode, p.stderr[-600:]))
        return
    width, height, pixels = read_png(shot)
    # the 3D view is the left 1020 x 714 pixels (the side panel and the bar are HTML)
    counts = {"car": 0, "blue": 0, "yellow": 0, "grey points": 0}
    for y in range(0, min(height, 714)):
        for (r, g, b) in pixels[y][:min(width, 1020)]:
            if r > 180 and g < 50 and b < 50:
                counts["car"] += 1
            elif b > 150 and r < 90 and g < 150:
                counts["blue"] += 1
            elif r > 150 and g > 120 and b < 70:
                counts["yellow"] += 1
            elif abs(r - g) < 10 and abs(g - b) < 10 and 115 < r < 165:
                counts["grey points"] += 1  # ground returns, coloured by label
    print("screenshot pixels: %s" % counts)
    for what, least in (("car", 2000), ("blue", 40), ("yellow", 40), ("grey points", 300)):
        if counts[what] < least:
            fail("screenshot: %d %s pixels, expected at least %d" % (counts[what], what, least))

    check_camera(top, run_dir)


def check_camera(top, lidar_run):
    """A stereo run's camera frames in the page's corner panel and in the camera video."""
    run_dir = os.path.join(top, "stereo")
    t0 = time.monotonic()
    run([BIN, "run", "autocross-stereo", "--no-plot", "--replay",
         "--set", "referee.timeout_autocross_s=%d" % CAMERA_LIMIT_S, "--out", run_dir],
        expect=(0, 1))
    print("stereo run: %.1f s" % (time.monotonic() - t0))
    page = os.path.join(run_dir, "replay.html")
    if not os.path.isfile(page):
        fail("the stereo run wrote no replay.html")
        return
    p, seconds = browser(os.path.join(top, "profile-camera"), "--virtual-time-budget=3000",
                         "--dump-dom", "file://" + page + "#t=%g" % T_CAMERA)
    state = page_state(p.stdout)
    print("chromium --dump-dom (camera): %.1f s" % seconds)
    if state is None:
        fail("no page state in the stereo run's DOM (exit %d): %s" % (p.returncode,
                                                                       p.stderr[-600:]))
        return
    cam = state.get("camera_frame")
    print("camera panel: %s" % json.dumps(cam))
    # 4 frames a second recorded: the one shown is the latest captured by the scrubbed time
    if not cam or not cam["shown"] or not cam["drawn"]:
        fail("no camera frame drawn at %s s: %s" % (T_CAMERA, cam))
        return
    if not (T_CAMERA - 0.3 <= cam["t"] <= T_CAMERA):
        fail("camera frame of %s s shown at %s s" % (cam["t"], T_CAMERA))
    if cam["frames"] < 3 * CAMERA_LIMIT_S:
        fail("%d camera frames recorded in a %d s run (4 a second)" % (cam["frames"],
                                                                       CAMERA_LIMIT_S))
    if cam["boxes"]["truth"] < 1 or cam["boxes"]["detected"] < 1:
        fail("the camera frame at %s s has no detected or no true boxes: %s" % (cam["t"],
                                                                                cam["boxes"]))
    # the camera video of the stereo run; the LiDAR run (no camera) is refused
    p = run([BIN, "view", run_dir, "--mp4-view", "camera", "--fps", "4"], expect=(0,))
    video = os.path.join(run_dir, "replay-camera.mp4")
    if not os.path.isfile(video) or os.path.getsize(video) < 1000:
        fail("view --mp4-view camera wrote no replay-camera.mp4")
    else:
        print("replay-camera.mp4: %.2f MB" % (os.path.getsize(video) / 1e6))
    p = run([BIN, "view", lidar_run, "--mp4-view", "camera"], expect=(2,))
    if not re.search(r"replay\.bin: has no camera frames", p.stderr):
        fail("camera video of a run without a camera: %s" % p.stderr.strip()[:300])
    leftovers = [n for n in os.listdir(lidar_run)
                 if n.startswith(".partial") or n == "replay-camera.mp4"]
    if leftovers:
        fail("a refused camera video left %s" % leftovers)


if __name__ == "__main__":
    main()
