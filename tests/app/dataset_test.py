#!/usr/bin/env python3
"""`conesim dataset` end to end (issue 17, docs/dataset.md), read as a trainer would read it.

A small dataset (8 frames from 2 runs, one frame a second), then from the files alone:
- every frame has its image (640 x 480 RGB), its YOLO label file (class 0-4, box inside the
  image), its class mask (8-bit) and instance mask (16-bit), its LiDAR sweep as binary PCD;
- each YOLO box holds its cone's pixels in the instance mask, of the box's class in the class
  mask; for a cone with nothing in front and wholly inside the image, the box and the box of its
  mask pixels overlap with IoU >= 0.9 (the renderer against the cone's mesh);
- the PCD's points carry labels: ground points class 1, cone points a cone class whose cone is
  in the frame's manifest or farther than the camera sees;
- the same command again gives the same files (the seed is all the randomness);
- bad input is refused with exit 2 naming the option or folder, before any folder is made.

usage: dataset_test.py CONESIM_BINARY
"""
import json
import os
import struct
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from app_checks import fail, failures, png_header_and_data, read_png, run  # noqa: E402

BIN = os.path.abspath(sys.argv[1])


def read_grey_png(path):
    """(width, height, bit depth, flat list of values) of a one-channel PNG with filter 0 rows
    (what conesim writes)."""
    width, height, depth, colour, _, raw = png_header_and_data(path)
    assert colour == 0, "%s: colour type %d, expected grey" % (path, colour)
    step = depth // 8
    stride = width * step
    values = []
    for r in range(height):
        row = raw[r * (stride + 1):(r + 1) * (stride + 1)]
        assert row[0] == 0, "%s: filter %d" % (path, row[0])
        if step == 1:
            values.extend(row[1:])
        else:
            values.extend(struct.unpack(">%dH" % width, row[1:]))
    return width, height, depth, values


def read_pcd(path):
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"DATA binary\n") + len(b"DATA binary\n")
    header = data[:end].decode()
    fields = dict(line.split(" ", 1) for line in header.splitlines() if not line.startswith("#"))
    n = int(fields["POINTS"])
    assert fields["FIELDS"] == "x y z intensity ring label class", fields["FIELDS"]
    body = data[end:]
    if len(body) != 23 * n:
        fail("%s: %d bytes of points, expected 23 x %d" % (path, len(body), n))
        return []
    return [struct.unpack_from("<ffffHiB", body, 23 * i) for i in range(n)]


def iou(a, b):
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


work = tempfile.mkdtemp(prefix="conesim_dataset_test_")
out = os.path.join(work, "ds")
args = [BIN, "dataset", "--frames", "8", "--runs", "2", "--every", "1", "--seed", "3"]

# bad input: exit 2, the option or folder named, no folder made
p = run(args[:2] + ["--frames", "0", "--out", os.path.join(work, "bad")], expect=[2])
if "--frames" not in p.stderr:
    fail("--frames 0 not named: " + p.stderr)
p = run(args + ["--set", "world.clutter.objects_per_100m=-1", "--out", os.path.join(work, "bad")],
        expect=[2])
if "objects_per_100m" not in p.stderr:
    fail("a bad --set not named: " + p.stderr)
if os.path.exists(os.path.join(work, "bad")):
    fail("bad input made a folder")
os.makedirs(os.path.join(work, "full"))
open(os.path.join(work, "full", "x"), "w").close()
p = run(args + ["--out", os.path.join(work, "full")], expect=[2])
if "not empty" not in p.stderr:
    fail("a folder with files in it not refused: " + p.stderr)

# the dataset
p = run(args + ["--out", out], expect=[0])
print(p.stdout.strip())
manifest = json.load(open(os.path.join(out, "manifest.json")))
if os.path.exists(os.path.join(out, "INCOMPLETE")):
    fail("a complete dataset has an INCOMPLETE file")
frames = manifest["frames"]
if len(frames) != 8 or manifest["summary"]["runs"] < 2:
    fail("%d frames from %d runs, expected 8 from at least 2" %
         (len(frames), manifest["summary"]["runs"]))
camera = manifest["camera"]
W, H = camera["width_px"], camera["height_px"]
checked, lidar_cone_points = 0, 0
for f in frames:
    w, h, _ = read_png(os.path.join(out, f["image"]))
    if (w, h) != (W, H):
        fail("%s is %dx%d" % (f["image"], w, h))
    cw, ch, cdepth, cls = read_grey_png(os.path.join(out, f["class_mask"]))
    iw, ih, idepth, inst = read_grey_png(os.path.join(out, f["instance_mask"]))
    if (cw, ch, cdepth, iw, ih, idepth) != (W, H, 8, W, H, 16):
        fail("%s masks: %s" % (f["image"], (cw, ch, cdepth, iw, ih, idepth)))
        continue
    boxed = [c for c in f["cones"] if c["boxed"]]
    lines = [l.split() for l in open(os.path.join(out, f["labels"])).read().splitlines()]
    if len(lines) != len(boxed):
        fail("%s: %d YOLO lines, %d boxed cones in the manifest" % (f["labels"], len(lines), len(boxed)))
        continue
    for line, cone in zip(lines, boxed):
        k, xc, yc, bw, bh = int(line[0]), *map(float, line[1:])
        if not (0 <= k <= 4 and 0 < bw <= 1 and 0 < bh <= 1 and 0 <= xc - bw / 2 + 1e-6
                and xc + bw / 2 <= 1 + 1e-6 and 0 <= yc - bh / 2 + 1e-6 and yc + bh / 2 <= 1 + 1e-6):
            fail("%s: line %s outside the image or class" % (f["labels"], line))
            continue
        box = ((xc - bw / 2) * W, (yc - bh / 2) * H, (xc + bw / 2) * W, (yc + bh / 2) * H)
        # the cone's pixels in the instance mask, their box, and their class in the class mask
        want = cone["cone_id"] + 1
        xs, ys, wrong_class, inside = [], [], 0, 0
        for i, v in enumerate(inst):
            if v != want:
                continue
            x, y = i % W, i // W
            xs.append(x)
            ys.append(y)
            wrong_class += cls[i] != 10 + k
            inside += box[0] <= x + 0.5 <= box[2] and box[1] <= y + 0.5 <= box[3]
        if not xs:
            fail("%s: cone %d boxed but not in the instance mask" % (f["image"], cone["cone_id"]))
            continue
        if wrong_class:
            fail("%s: %d pixels of cone %d not class %d" % (f["class_mask"], wrong_class, cone["cone_id"], 10 + k))
        if inside < 0.95 * len(xs):
            fail("%s: only %d of cone %d's %d pixels in its box" % (f["image"], inside, cone["cone_id"], len(xs)))
        mask_box = (min(xs), min(ys), max(xs) + 1, max(ys) + 1)
        if cone["occlusion"] == 0 and cone["truncation"] == 0 and min(box[2] - box[0], box[3] - box[1]) >= 12:
            checked += 1
            if iou(box, mask_box) < 0.9:
                fail("%s: cone %d box %s against its mask's %s: IoU %.3f" %
                     (f["image"], cone["cone_id"], box, mask_box, iou(box, mask_box)))
    if f["lidar"] is None:
        fail("%s has no LiDAR sweep" % f["image"])
        continue
    points = read_pcd(os.path.join(out, f["lidar"]))
    classes = {}
    for x, y, z, intensity, ring, label, c in points:
        if label == -1 and c != 1:
            fail("%s: a ground point of class %d" % (f["lidar"], c))
            break
        if label >= 0:
            lidar_cone_points += 1
            if not 10 <= c <= 14:
                fail("%s: a point of cone %d has class %d" % (f["lidar"], label, c))
                break
            if classes.setdefault(label, c) != c:
                fail("%s: cone %d's points have two classes" % (f["lidar"], label))
                break
    # a cone the camera boxes and the LiDAR hits has one class in both
    for cone in f["cones"]:
        if cone["cone_id"] in classes:
            k = manifest["yolo_classes"].index(cone["class"])
            if classes[cone["cone_id"]] != 10 + k:
                fail("%s: cone %d class %d in the LiDAR, %d in the camera" %
                     (f["lidar"], cone["cone_id"], classes[cone["cone_id"]], 10 + k))
print("measured: %d unhidden boxes checked against their masks, %d LiDAR cone points" %
      (checked, lidar_cone_points))
if checked < 5:
    fail("only %d boxes of unhidden cones to check, expected at least 5" % checked)
if lidar_cone_points < 100:
    fail("only %d LiDAR points on cones" % lidar_cone_points)
w, h, _ = read_png(os.path.join(out, "contact_sheet.png"))
if (w, h) != (2 * W, H):  # 8 frames at half size, four to a row
    fail("contact sheet %dx%d, expected %dx%d" % (w, h, 2 * W, H))
if "large_orange_cone" not in open(os.path.join(out, "data.yaml")).read():
    fail("data.yaml lacks the class names")

# determinism: the same command again, the same labels and manifest but for the wall time
again = os.path.join(work, "again")
run(args + ["--out", again], expect=[0])
m2 = json.load(open(os.path.join(again, "manifest.json")))
for m in (manifest, m2):
    m["summary"].pop("wall_s")
if m2 != manifest:
    fail("the same seed gave another manifest")
for f in frames:
    for key in ("labels", "class_mask", "instance_mask", "image", "lidar"):
        a = open(os.path.join(out, f[key]), "rb").read()
        b = open(os.path.join(again, f[key]), "rb").read()
        if a != b:
            fail("the same seed gave another %s" % f[key])

subprocess.run(["rm", "-rf", work])
if failures:
    print("%d failed" % len(failures))
    sys.exit(1)
print("all passed")
