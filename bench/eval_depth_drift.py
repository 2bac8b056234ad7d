#!/usr/bin/python3
"""Drift of a registered depth sequence against its true poses.

Usage: eval_depth_drift.py REGISTER.json POSES_TRUE.txt

REGISTER.json is the output of `strata register depth --json` (one sequence; a
sequence imported without --poses has no recorded poses to evaluate); the
true poses are the synthetic sequence's poses_true.txt ('file tx ty tz qx qy qz qw',
camera -> site frame). For the poses the device recorded, those after frame-to-model
tracking and the final ones (after loop closure and re-registration), per frame: the
distance between the estimated and the true camera centre and the angle of
R_true^T R_estimated. Prints one JSON object with, for each set, the largest, RMS and
last frame's errors (mm, mrad), and the median per-frame RMS residual and pose sigmas.
"""
import json
import math
import sys

import numpy as np


def quaternion_matrix(qx, qy, qz, qw):
    x, y, z, w = qx, qy, qz, qw
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def read_truth(path):
    out = {}
    for line in open(path):
        if line.startswith("#") or not line.strip():
            continue
        f = line.split()
        v = [float(x) for x in f[1:]]
        out[f[0]] = (np.array(v[:3]), quaternion_matrix(*v[3:]))
    return out


def errors(frames, truth, key):
    pos, rot = [], []
    for fr in frames:
        m = np.array(fr[key]).reshape(4, 4)
        t, r = truth[fr["frame"]]
        pos.append(1000 * np.linalg.norm(m[:3, 3] - t))
        c = (np.trace(r.T @ m[:3, :3]) - 1) / 2
        rot.append(1000 * math.acos(max(-1.0, min(1.0, c))))
    pos, rot = np.array(pos), np.array(rot)
    return {"position_max_mm": float(pos.max()), "position_rms_mm": float(math.sqrt((pos ** 2).mean())),
            "position_last_mm": float(pos[-1]), "rotation_max_mrad": float(rot.max()),
            "rotation_rms_mrad": float(math.sqrt((rot ** 2).mean())), "rotation_last_mrad": float(rot[-1])}


def main():
    reg = json.load(open(sys.argv[1]))
    truth = read_truth(sys.argv[2])
    seq = reg["sequences"][0]
    frames = seq["frames"]
    out = {"frames": len(frames), "loop_closed": seq["loop_closed"], "loop_correction_mm": 1000 * seq["loop_correction_m"],
           "loop_correction_mrad": 1000 * seq["loop_correction_rad"], "seconds": seq["seconds"]}
    for name, key in (("recorded", "recorded_pose"), ("tracked", "tracked_pose"), ("final", "pose")):
        if all(key in f for f in frames):  # no recorded poses: imported without --poses
            out[name] = errors(frames, truth, key)
    out["datum"] = seq.get("datum", {}).get("datum", "device")
    out["starts"] = {s: sum(1 for f in frames if f.get("start") == s)
                     for s in ("features", "recorded", "constant-velocity")}
    if "rms_m" in seq.get("datum", {}):
        out["marker_rms_mm"] = 1000 * seq["datum"]["rms_m"]
        out["marker_inliers"] = seq["datum"]["inliers"]
        out["markers_seen"] = len(seq["datum"]["markers"])
    out["residual_rms_median_mm"] = 1000 * float(np.median([f["rms_m"] for f in frames]))
    out["residual_rms_max_mm"] = 1000 * float(max(f["rms_m"] for f in frames))
    out["inlier_share_min"] = float(min(f["inlier_share"] for f in frames))
    out["sigma_translation_median_mm"] = 1000 * float(np.median([f["sigma_translation_m"] for f in frames]))
    out["sigma_rotation_median_mrad"] = 1000 * float(np.median([f["sigma_rotation_rad"] for f in frames]))
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
