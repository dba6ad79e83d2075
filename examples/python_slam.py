"""A landmark SLAM in Python, run as the SLAM of a normal `conesim run` (docs/sdk.md, "Python"):
dead reckoning on conesim's odometry, nearest-neighbour association, and a pull of the pose
towards the mapped cones it sees again; landmarks are running means, confirmed after three
sightings.

    ./conesim run autocross --set perception=cone_sensor --set 'autonomy.slam={plugin:
        build/python/libconesim_python_plugin.so, config: {file: examples/python_slam.py,
        class: NearestNeighbourSlam}}'
"""
import math

import conesim
import numpy as np


class NearestNeighbourSlam:
    def __init__(self, run, options):
        self.gate_m = float(options.get("gate_m", 1.0))  # an observation this near is that landmark
        self.pull = float(options.get("pull", 0.5))  # share of the matched cones' offset per frame
        self.confirm = 3  # sightings before a landmark is in the map
        self.reset(run["start_pose"], 0.0, None)

    def reset(self, start_pose, t_s, prior_map):
        self.pose = np.array(start_pose, dtype=float)
        self.sums, self.counts, self.votes = np.zeros((0, 2)), np.zeros(0), np.zeros((0, 5))
        self.codes, self.started = [], []

    def process(self, inp):
        # predict: the odometry's motion since the last frame, in the vehicle frame
        dx, dy, dyaw = inp["odometry"]["delta"]
        x, y, yaw = self.pose
        c, s = math.cos(yaw), math.sin(yaw)
        self.pose = np.array([x + c * dx - s * dy, y + s * dx + c * dy, yaw + dyaw])
        # the cones in the map frame, each paired with the nearest landmark within the gate
        cones = inp["cones"]
        world = self.pose[:2] + cones @ np.array([[c, s], [-s, c]])
        means = self.sums / np.maximum(self.counts, 1)[:, None]
        nearest = np.full(len(world), -1)
        if len(means) and len(world):
            d = np.linalg.norm(world[:, None, :] - means[None, :, :], axis=2)
            nearest = np.where(d.min(axis=1) < self.gate_m, d.argmin(axis=1), -1)
        # correct: move part of the way onto the confirmed landmarks seen again
        seen = nearest >= 0
        seen[seen] = self.counts[nearest[seen]] >= self.confirm
        if seen.any():
            offset = self.pull * (means[nearest[seen]] - world[seen]).mean(axis=0)
            self.pose[:2] += offset
            world = world + offset
        # update the landmarks (running means, class votes); new ones for the rest
        self.codes, self.started = nearest.tolist(), [-1] * len(world)
        for i, (p, cls) in enumerate(zip(world, inp["cone_classes"])):
            j = nearest[i]
            if j < 0:
                j = len(self.counts)
                self.sums = np.vstack([self.sums, np.zeros(2)])
                self.counts, self.votes = np.append(self.counts, 0), np.vstack([self.votes, np.zeros(5)])
                self.started[i] = j
            self.sums[j] += p
            self.counts[j] += 1
            if cls != conesim.UNKNOWN:
                self.votes[j, cls] += 1

    def estimate(self):
        ids = np.flatnonzero(self.counts >= self.confirm)
        classes = np.where(self.votes[ids].sum(axis=1) > 0, self.votes[ids].argmax(axis=1), conesim.UNKNOWN)
        return {"pose": self.pose, "map": self.sums[ids] / self.counts[ids, None],
                "map_classes": classes.astype(np.int32), "map_ids": ids.astype(np.int32)}

    def associations(self):
        """Per observation of the last frame: the landmark it matched, or -1 for a new one."""
        return self.codes

    def new_landmark_ids(self):
        """Per observation that started a landmark, its id (scored like conesim's back-ends)."""
        return self.started
