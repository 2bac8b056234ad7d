#!/usr/bin/python3
"""Field-like marker clicks on a synthetic layer, and how well strata georeferences with them.

Usage:
  field_markers.py clicks DATASET LAYER OUT_GCP [--spread M] [--gross F] [--round M] [--seed N]
  field_markers.py score DATASET LAYER CAMERAS_CSV QUALITY_JSON

`clicks` writes an OpenDroneMap gcp_list as a user of another photogrammetry program
would export it for the synthetic DATASET (from `strata synth`): every photo that sees
a marker (the generator's gcp_list) gets a click, not at the true centre but at the
point of a marker *object* that this view shows (the centre moved by N(0, spread) per
axis, metres: an object ~10 cm across seen from every side), plus 1 px of click noise;
a fraction `gross` of the clicks is placed 20-80 px off (projected rather than clicked);
the survey coordinates (the generator's surveyed markers.csv) are rounded to `round`
metres. Only Python 3 and numpy (Debian python3-numpy).

`score` compares strata's cameras (export cameras --format csv) with the truth cameras
(absolute: the georeference is what is measured) and prints one JSON object:
registered, centre_rmse_mm, centre_max_mm, markers_used, per-marker dispersion.
"""
import csv
import json
import math
import os
import random
import sys

import numpy as np


def read_cameras(path):
    cams = {}
    with open(path) as f:
        for row in csv.DictReader(f):
            R = np.array([float(row[f"r{i}{j}"]) for i in range(1, 4) for j in range(1, 4)]).reshape(3, 3)
            C = np.array([float(row["X"]), float(row["Y"]), float(row["Z"])])
            cams[row["image"]] = dict(fx=float(row["fx"]), fy=float(row["fy"]), cx=float(row["ppx"]),
                                      cy=float(row["ppy"]), k1=float(row["k1"]), k2=float(row["k2"]), R=R, C=C)
    return cams


def project(cam, X):
    Xc = cam["R"] @ (X - cam["C"])
    if Xc[2] <= 0:
        return None
    x, y = Xc[0] / Xc[2], Xc[1] / Xc[2]
    r2 = x * x + y * y
    d = 1 + cam["k1"] * r2 + cam["k2"] * r2 * r2
    return np.array([cam["fx"] * x * d + cam["cx"], cam["fy"] * y * d + cam["cy"]])


def read_markers(path):
    out = {}
    with open(path) as f:
        for row in csv.DictReader(f):
            out[row["name"]] = np.array([float(row["E"]), float(row["N"]), float(row["Z"])])
    return out


def clicks(args):
    dataset, layer, out = args[0], args[1], args[2]
    opts = dict(spread=0.02, gross=0.2, round=0.1, seed=1)
    i = 3
    while i < len(args):
        opts[args[i].lstrip("-")] = float(args[i + 1])
        i += 2
    rng = random.Random(int(opts["seed"]))
    truth_cams = read_cameras(os.path.join(dataset, "truth", layer, "cameras.csv"))
    truth = read_markers(os.path.join(dataset, "truth", "markers.csv"))
    surveyed = read_markers(os.path.join(dataset, "markers.csv"))
    step = opts["round"]
    lines, gross = [], 0
    with open(os.path.join(dataset, "gcp_list.txt")) as f:
        crs = f.readline().strip()
        for line in f:
            parts = line.rstrip("\n").split("\t")
            if len(parts) < 7:
                continue
            image, name = parts[5], parts[6]
            if image not in truth_cams:
                continue
            seen = truth[name] + np.array([rng.gauss(0, opts["spread"]) for _ in range(3)])
            p = project(truth_cams[image], seen)
            if p is None:
                continue
            p = p + np.array([rng.gauss(0, 1.0), rng.gauss(0, 1.0)])
            if rng.random() < opts["gross"]:
                a, d = rng.uniform(0, 2 * math.pi), rng.uniform(20, 80)
                q = p + d * np.array([math.cos(a), math.sin(a)])
                cam = truth_cams[image]
                # Kept inside the photo (the principal point is near its centre).
                if 0 <= q[0] <= 2 * cam["cx"] and 0 <= q[1] <= 2 * cam["cy"]:
                    p = q
                    gross += 1
            cam = truth_cams[image]
            if not (0 <= p[0] <= 2 * cam["cx"] and 0 <= p[1] <= 2 * cam["cy"]):
                continue  # the clicked point of the object falls outside this photo
            s = surveyed[name]
            r = [round(v / step) * step for v in s]
            lines.append(f"{r[0]:.3f}\t{r[1]:.3f}\t{r[2]:.3f}\t{p[0]:.2f}\t{p[1]:.2f}\t{image}\t{name}")
    with open(out, "w") as f:
        f.write(crs + "\n")
        f.write("\n".join(lines) + "\n")
    print(json.dumps({"clicks": len(lines), "gross_clicks": gross, **opts}))


def score(args):
    dataset, layer, cameras_csv, quality_json = args
    truth = read_cameras(os.path.join(dataset, "truth", layer, "cameras.csv"))
    est = read_cameras(cameras_csv)
    d = [np.linalg.norm(est[k]["C"] - truth[k]["C"]) for k in est if k in truth]
    with open(quality_json) as f:
        q = json.load(f)
    q = q[0] if isinstance(q, list) else q
    q = q.get("sparse", q)
    markers = [{"marker": m["marker"], "role": m["role"], "agree": m.get("images"), "observed": m.get("observed"),
                "dispersion_mm": 1000 * m.get("dispersion_m", 0.0),
                "error_mm": 1000 * math.sqrt(m["dE"] ** 2 + m["dN"] ** 2 + m["dZ"] ** 2) if m["triangulated"] else None}
               for m in q.get("markers", [])]
    print(json.dumps({
        "registered": len(d), "photos": len(truth),
        "georeferenced": q.get("georeferenced"),
        "centre_rmse_mm": 1000 * math.sqrt(sum(x * x for x in d) / len(d)) if d else None,
        "centre_max_mm": 1000 * max(d) if d else None,
        "control_rmse_mm": 1000 * q["control_rmse"]["xyz_m"] if q.get("georeferenced") else None,
        "markers_used": q["control_rmse"]["markers"] if q.get("georeferenced") else 0,
        "markers_given": len(q.get("markers", [])),
        "left_out": len(q.get("blunders", [])),
        "markers": markers,
    }, indent=1))


if __name__ == "__main__":
    if len(sys.argv) < 2 or sys.argv[1] not in ("clicks", "score"):
        print(__doc__)
        sys.exit(2)
    (clicks if sys.argv[1] == "clicks" else score)(sys.argv[2:])
