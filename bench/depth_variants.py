#!/usr/bin/python3
"""The DTM of a depth-only layer fused at other poses than the registered ones.

Usage: depth_variants.py KEEP_DIR [LAYER]

KEEP_DIR is a folder kept by `bench/depth.sh --keep KEEP_DIR`. For each of the poses
the device recorded, those after frame-to-model tracking (before loop closure; both
from register.json) and the true poses (data/depth/LAYER/poses_true.txt), a copy of
the project gets its frames' `pose` replaced and is processed again; then its DTM is
compared with the truth (bench/eval_surface.py). With the final poses' project also
processed at --voxel-size 0.008. Prints one JSON object.
"""
import json
import os
import shutil
import sqlite3
import subprocess
import sys

import numpy as np


def quaternion_matrix(qx, qy, qz, qw):
    x, y, z, w = qx, qy, qz, qw
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]


def true_poses(path):
    out = {}
    for line in open(path):
        if line.startswith("#") or not line.strip():
            continue
        f = line.split()
        v = [float(a) for a in f[1:]]
        m = np.eye(4)
        m[:3, :3] = quaternion_matrix(*v[3:])
        m[:3, 3] = v[:3]
        out[f[0]] = list(m.flatten())
    return out


def main():
    keep = sys.argv[1]
    layer = sys.argv[2] if len(sys.argv) > 2 else "L4"
    here = os.path.dirname(os.path.abspath(__file__))
    strata = os.path.join(here, "..", os.environ.get("STRATA_BUILD_DIR", "build"), "src", "cli", "strata")
    frames = json.load(open(f"{keep}/register.json"))["sequences"][0]["frames"]
    variants = {"recorded": {f["frame"]: f["recorded_pose"] for f in frames},
                "tracked": {f["frame"]: f["tracked_pose"] for f in frames},
                "true": true_poses(f"{keep}/data/depth/{layer}/poses_true.txt"),
                "final_voxel_8mm": None}
    out = {}
    for name, poses in variants.items():
        proj = f"{keep}/depth_{name}"
        shutil.rmtree(proj, ignore_errors=True)
        shutil.copytree(f"{keep}/depth", proj)
        extra = []
        if poses is None:
            extra = ["--voxel-size", "0.008"]
        else:
            db = sqlite3.connect(f"{proj}/project.gpkg")
            for fid, frame in db.execute("SELECT id, name FROM depth_frames").fetchall():
                db.execute("UPDATE depth_frames SET pose = ? WHERE id = ?",
                           (" ".join("%.17g" % x for x in poses[frame]), fid))
            db.commit()
            db.close()
        subprocess.run([strata, "-q", "process", proj, "--layer", layer, "--json"] + extra, check=True,
                       stdout=subprocess.DEVNULL)
        r = subprocess.run(["/usr/bin/python3", f"{here}/eval_surface.py", f"{proj}/products/{layer}/dtm.tif",
                            f"{keep}/data/truth/{layer}/surface.tif", f"{keep}/data/site.json"],
                           check=True, capture_output=True, text=True)
        out[name] = json.loads(r.stdout)
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
