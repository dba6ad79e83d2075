#!/usr/bin/env python3
"""The review images and the video (issue 16, docs/review.md), as a user would look at them.

A short LiDAR + SLAM run on the layout with a cone in the lane, with its LiDAR dumped every 5th
sweep, then:
- the LiDAR review image of a sweep whose sidecar lists a missed cone shows the miss marker (the
  legend's pure red cross) at that cone's place in the picture, and a found cone's place shows the
  found ring (green) and no miss marker;
- `conesim view RUN --mp4` gives a replay.mp4 (and `--mp4-view chase` a replay-chase.mp4) that
  ffprobe reads as H.264 with the expected frame count and duration, whose frames are not
  uniform and change as the car drives;
- bad input is refused with exit 2 and the file named, and never leaves a replay.mp4: a folder
  that is not a run, one without trajectory.csv, ffmpeg missing, ffmpeg failing.

usage: review_test.py CONESIM_BINARY TEST_DATA_DIR
"""
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from app_checks import fail, failures, read_png, run  # noqa: E402

BIN = os.path.abspath(sys.argv[1])
DATA = os.path.abspath(sys.argv[2])
TRACK = os.path.join(DATA, "replay", "cone_in_the_lane.csv")
FPS = 10
def is_miss_red(rgb):
    return rgb[0] > 200 and rgb[1] < 60 and rgb[2] < 60


def is_found_green(rgb):
    return rgb[1] > 130 and rgb[0] < 80 and rgb[2] < 80


def near(rows, x, y, test, radius):
    """Whether a pixel within `radius` of (x, y) passes `test`."""
    for j in range(max(0, y - radius), min(len(rows), y + radius + 1)):
        for i in range(max(0, x - radius), min(len(rows[0]), x + radius + 1)):
            if test(rows[j][i]):
                return True
    return False


def check_lidar_review(run_dir):
    folder = os.path.join(run_dir, "images", "lidar")
    sidecars = sorted(n for n in os.listdir(folder) if n.endswith(".json"))
    if not sidecars:
        fail("no LiDAR sweep dumped")
        return
    checked = 0
    for name in sidecars:
        with open(os.path.join(folder, name)) as f:
            side = json.load(f)
        if not side.get("missed"):
            continue
        found = [d for d in side.get("detections", []) if d["true_cone_id"] != -1]
        png = os.path.join(folder, name.replace(".json", ".png"))
        width, height, rows = read_png(png)
        left, top, right, bottom = side["review_png"]["plot_px_left_top_right_bottom"]
        r = side["review_png"]["range_m"]

        def pixel(x_m, y_m):
            return (int(round(left + (x_m + r) / (2 * r) * (right - left))),
                    int(round(bottom - (y_m + r) / (2 * r) * (bottom - top))))

        missed_px = [pixel(m["x_sensor"], m["y_sensor"]) for m in side["missed"]]
        for m, (x, y) in zip(side["missed"], missed_px):
            if not near(rows, x, y, is_miss_red, 4):
                fail("%s: no miss marker (red cross) at missed cone %d, pixel (%d, %d)"
                     % (png, m["true_cone_id"], x, y))
        for d in found:
            x, y = pixel(d["x_sensor"], d["y_sensor"])
            if any(abs(x - mx) < 30 and abs(y - my) < 30 for mx, my in missed_px):
                continue  # too close to a miss to tell apart
            if not near(rows, x, y, is_found_green, 14):
                fail("%s: no found ring (green) at detection (%d, %d)" % (png, x, y))
            if near(rows, x, y, is_miss_red, 4):
                fail("%s: a miss marker at a found cone, pixel (%d, %d)" % (png, x, y))
        # the legend (right of the plot) names the miss marker in its colour
        if not any(is_miss_red(rows[j][i]) for j in range(top, bottom)
                   for i in range(right + 10, width)):
            fail("%s: no miss marker in the legend" % png)
        checked += 1
        print("lidar review: %s, %d missed, %d found" % (name, len(side["missed"]), len(found)))
        if checked == 2:
            break
    if checked == 0:
        fail("no dumped sweep has a missed cone (expected the far cones with few points)")


def ffprobe(path):
    p = run(["ffprobe", "-v", "error", "-select_streams", "v:0", "-count_frames",
             "-show_entries", "stream=codec_name,width,height,nb_read_frames,pix_fmt:"
             "format=duration", "-of", "json", path], expect=(0,))
    return json.loads(p.stdout) if p.returncode == 0 else None


def frame_at(path, t_s, width, height):
    p = subprocess.run(["ffmpeg", "-v", "error", "-ss", str(t_s), "-i", path, "-frames:v", "1",
                        "-f", "rawvideo", "-pix_fmt", "rgb24", "-"], stdout=subprocess.PIPE,
                       timeout=120)
    return p.stdout if len(p.stdout) == 3 * width * height else None


def check_video(run_dir, top):
    check_encoded(run_dir, ["--mp4"], "replay.mp4")
    check_encoded(run_dir, ["--mp4-view", "chase"], "replay-chase.mp4")
    check_refusals(run_dir, top)


def check_encoded(run_dir, flags, name):
    with open(os.path.join(run_dir, "trajectory.csv")) as f:
        times = [float(line.split(",")[0]) for line in f.readlines()[1:] if line.strip()]
    frames = 1 + math.floor((times[-1] - times[0]) * FPS + 1e-9)
    run([BIN, "view", run_dir] + flags + ["--fps", str(FPS)], expect=(0,))
    video = os.path.join(run_dir, name)
    if not os.path.isfile(video):
        fail("view %s wrote no %s" % (" ".join(flags), name))
        return
    if [n for n in os.listdir(run_dir) if n.startswith(".partial")]:
        fail("a partial file was left beside " + name)
    info = ffprobe(video)
    if info is None:
        return
    stream = info["streams"][0]
    duration = float(info["format"]["duration"])
    print("%s: %s %dx%d %s, %s frames, %.2f s, %.2f MB" % (
        name, stream["codec_name"], stream["width"], stream["height"], stream["pix_fmt"],
        stream["nb_read_frames"], duration, os.path.getsize(video) / 1e6))
    if stream["codec_name"] != "h264" or stream["pix_fmt"] != "yuv420p":
        fail("%s is %s %s, expected h264 yuv420p" % (name, stream["codec_name"],
                                                    stream["pix_fmt"]))
    if int(stream["nb_read_frames"]) != frames:
        fail("%s has %s frames, expected %d (%.2f s of trajectory at %d fps)" % (
            name, stream["nb_read_frames"], frames, times[-1] - times[0], FPS))
    if abs(duration - frames / FPS) > 1.5 / FPS:
        fail("%s lasts %.2f s, expected %.2f" % (name, duration, frames / FPS))
    w, h = stream["width"], stream["height"]
    early, late = frame_at(video, 0.5, w, h), frame_at(video, duration - 0.5, w, h)
    if early is None or late is None:
        fail("ffmpeg could not decode frames of " + name)
        return
    colours = len(set(early[i:i + 3] for i in range(0, len(early), 3 * 7)))
    if colours < 20:
        fail("%s: the first frame looks uniform: %d colours" % (name, colours))
    changed = sum(1 for i in range(0, len(early), 3) if abs(early[i] - late[i]) > 40)
    print("%s frames: %d colours early, %d pixels changed by the end" % (name, colours, changed))
    if changed < 500:
        fail("%s barely changes as the car drives: %d pixels" % (name, changed))


def check_refusals(run_dir, top):
    # bad input: exit 2, the file named, no replay.mp4
    def refused(name, folder, needle, env=None):
        p = run([BIN, "view", folder, "--mp4"], env=env)
        if p.returncode != 2 or needle not in p.stderr:
            fail("%s: exit %d, expected 2 naming %s: %s" % (name, p.returncode, needle,
                                                            p.stderr.strip()[:300]))
        if os.path.exists(os.path.join(folder, "replay.mp4")) or \
                (os.path.isdir(folder) and any(n.startswith(".partial")
                                               for n in os.listdir(folder))):
            fail("%s: left a replay.mp4 or a partial file" % name)

    refused("no folder", os.path.join(top, "nowhere"), "nowhere")
    bare = os.path.join(top, "bare")
    shutil.copytree(run_dir, bare, ignore=shutil.ignore_patterns("images", "replay.mp4"))
    os.remove(os.path.join(bare, "trajectory.csv"))
    refused("no trajectory", bare, "trajectory.csv")
    copy = os.path.join(top, "copy")
    shutil.copytree(run_dir, copy, ignore=shutil.ignore_patterns("images", "replay.mp4"))
    env = dict(os.environ, CONESIM_FFMPEG=os.path.join(top, "no-ffmpeg"))
    refused("ffmpeg missing", copy, "ffmpeg", env)
    failing = os.path.join(top, "failing-ffmpeg")
    with open(failing, "w") as f:
        f.write("#!/bin/sh\ncat >/dev/null\necho 'broken encoder' >&2\nexit 1\n")
    os.chmod(failing, 0o755)
    refused("ffmpeg failing", copy, "replay.mp4", dict(os.environ, CONESIM_FFMPEG=failing))
    # the camera video of a run without camera frames: refused before ffmpeg starts
    p = run([BIN, "view", copy, "--mp4-view", "camera"])
    if p.returncode != 2 or "replay.bin: has no camera frames" not in p.stderr:
        fail("camera video without camera frames: exit %d: %s" % (p.returncode,
                                                                  p.stderr.strip()[:300]))
    if any(n.startswith(".partial") or n == "replay-camera.mp4" for n in os.listdir(copy)):
        fail("a refused camera video left a file")


def main():
    if not shutil.which("ffmpeg") or not shutil.which("ffprobe"):
        print("FAIL no ffmpeg/ffprobe in PATH: install Debian's ffmpeg (debian-packages.txt; "
              "./conesim installs it)")
        sys.exit(1)
    top = tempfile.mkdtemp(prefix="conesim-review-")
    try:
        run_dir = os.path.join(top, "run")
        run([BIN, "run", "trackdrive-lidar", "--track", TRACK, "--replay", "--dump", "lidar",
             "--dump-every", "5", "--set", "referee.timeout_trackdrive_total_s=8",
             "--out", run_dir], expect=(0, 1))
        if not os.path.isfile(os.path.join(run_dir, "trajectory.csv")):
            fail("the run wrote no trajectory.csv")
        else:
            check_lidar_review(run_dir)
            check_video(run_dir, top)
    finally:
        shutil.rmtree(top, ignore_errors=True)
    if failures:
        print("%d check(s) failed" % len(failures))
        sys.exit(1)
    print("review: all checks passed")


main()
