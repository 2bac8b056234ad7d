#!/usr/bin/python3
"""How far registered depth frames stand above (or below) their true poses.

Usage: eval_frame_lift.py REGISTER.json SEQ_DIR [--key pose|tracked_pose|recorded_pose]

REGISTER.json is `strata register depth --json` (bench/depth.sh --keep leaves it as
register.json); SEQ_DIR the synthetic sequence's folder (intrinsics.txt,
poses_true.txt, depth/). Each frame's pixels (every 8th each way) are
back-projected and placed by the registered and by the true pose; the frame's lift
is the median of z(registered) - z(true) over them: what the registration alone
moves that frame's surface up or down. Prints one JSON object: the mean, median,
smallest and largest lift over the frames (mm), and the same for the camera centres.
Needs python3-gdal and python3-numpy (run it with /usr/bin/python3).
"""
import argparse
import json
import os
import sys

import numpy as np
from osgeo import gdal

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from eval_colour import read_key_values  # noqa: E402
from eval_depth_drift import read_truth  # noqa: E402

gdal.UseExceptions()
STEP = 8  # pixels


def figures(v):
    v = np.array(v) * 1e3
    return {"mean_mm": float(v.mean()), "median_mm": float(np.median(v)), "min_mm": float(v.min()),
            "max_mm": float(v.max())}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("register_json")
    ap.add_argument("seq")
    ap.add_argument("--key", default="pose")
    args = ap.parse_args()
    k = read_key_values(os.path.join(args.seq, "intrinsics.txt"))
    truth = read_truth(os.path.join(args.seq, "poses_true.txt"))
    lift, centre = [], []
    for f in json.load(open(args.register_json))["sequences"][0]["frames"]:
        P = np.array(f[args.key]).reshape(4, 4)
        t, R = truth[f["frame"]]
        ds = gdal.Open(os.path.join(args.seq, "depth", f["frame"]))  # held: its band needs it
        depth = ds.GetRasterBand(1).ReadAsArray()
        v, u = np.mgrid[0:depth.shape[0]:STEP, 0:depth.shape[1]:STEP]
        z = depth[::STEP, ::STEP].astype(np.float64) * 1e-3
        m = z > 0
        X = np.stack([(u[m] - k["cx"]) * z[m] / k["fx"], (v[m] - k["cy"]) * z[m] / k["fy"], z[m]])
        lift.append(np.median((P[:3, :3] @ X + P[:3, 3:4])[2] - (R @ X + t[:, None])[2]))
        centre.append(P[2, 3] - t[2])
    print(json.dumps({"key": args.key, "frames": len(lift), "lift": figures(lift), "camera_centre_dz": figures(centre)}))


if __name__ == "__main__":
    main()
