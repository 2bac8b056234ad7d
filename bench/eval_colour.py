#!/usr/bin/python3
"""Colour of a fused depth-only layer against the colour its frames saw.

Usage: eval_colour.py POINTS.ply SITE.json SEQ_DIR [--sample N] [--seed S]

POINTS.ply is the layer's points.ply (binary, site CRS coordinates, red/green/blue);
SEQ_DIR the synthetic sequence's folder (data/depth/L<k>: intrinsics.txt,
poses_true.txt, depth/, colour/). The reference colour of a point is what the colour
frames show at it: the point is projected into every frame at its TRUE pose, kept
where the frame's depth at that pixel is within 2 cm of the point's (it is seen, not
hidden), and the nearest pixel's colour is taken; the reference is the per-channel
median over the frames that see it. The synthetic colour frames are the surface's
unlit albedo, so the reference is the albedo at the point, blurred by one pixel
footprint (about 4 mm at 2 m).

Prints one JSON object over the points of a random sample (default 200000) that at
least one frame sees:
  points_compared
  rms_levels          RMS of (fused - reference) over the points and the 3 channels, 8-bit levels
  median_abs_levels   median over points of the largest |channel difference|
  grey_rms_levels     the same RMS for a uniform mid grey (128), what frames without colour give
  mean_rms_levels     the same RMS for the reference's mean colour (the best uniform colour)
  grey_share          share of points whose colour is exactly (128, 128, 128)
Needs python3-gdal and python3-numpy (run it with /usr/bin/python3).
"""
import argparse
import json
import os
import sys
import warnings

import numpy as np
from osgeo import gdal

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from eval_depth_drift import read_truth  # noqa: E402

gdal.UseExceptions()

VISIBLE_TOLERANCE_M = 0.02  # metres: the frame's depth there within this of the point's


def read_ply_points(path):
    with open(path, "rb") as f:
        header = []
        while True:
            line = f.readline().decode("ascii").strip()
            header.append(line)
            if line == "end_header":
                break
        offset = f.tell()
    if "format binary_little_endian 1.0" not in header:
        raise SystemExit(f"eval_colour: {path}: not a binary little-endian PLY")
    n = next(int(h.split()[2]) for h in header if h.startswith("element vertex"))
    types = {"double": "<f8", "float": "<f4", "uchar": "u1", "int": "<i4", "uint": "<u4"}
    props = [h.split() for h in header if h.startswith("property")]
    dtype = np.dtype([(p[2], types[p[1]]) for p in props])
    v = np.fromfile(path, dtype=dtype, count=n, offset=offset)
    return np.stack([v["x"], v["y"], v["z"]], 1), np.stack([v["red"], v["green"], v["blue"]], 1).astype(np.float64)


def read_key_values(path):
    out = {}
    for line in open(path):
        line = line.split("#")[0].replace(",", " ").split()
        if len(line) == 2:
            out[line[0]] = float(line[1])
    return out


def read_image(path):
    ds = gdal.Open(path)
    return np.stack([ds.GetRasterBand(b + 1).ReadAsArray() for b in range(ds.RasterCount)], -1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("points")
    ap.add_argument("site_json")
    ap.add_argument("seq")
    ap.add_argument("--sample", type=int, default=200000)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()

    origin = np.array(json.load(open(args.site_json))["origin"])
    xyz, rgb = read_ply_points(args.points)
    rng = np.random.default_rng(args.seed)
    if len(xyz) > args.sample:
        pick = rng.choice(len(xyz), args.sample, replace=False)
        xyz, rgb = xyz[pick], rgb[pick]
    site = xyz - origin
    k = read_key_values(os.path.join(args.seq, "intrinsics.txt"))
    w, h = int(k["width"]), int(k["height"])
    samples = []  # per frame: colours (NaN where not seen)
    for name, (t, R) in read_truth(os.path.join(args.seq, "poses_true.txt")).items():
        cam = (site - t) @ R  # R^T (X - t), row vectors
        z = cam[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.rint(k["fx"] * cam[:, 0] / z + k["cx"])
            r = np.rint(k["fy"] * cam[:, 1] / z + k["cy"])
        inside = (z > 0) & (u >= 0) & (u < w) & (r >= 0) & (r < h)
        depth = read_image(os.path.join(args.seq, "depth", name))[..., 0].astype(np.float64) * 1e-3
        colour = read_image(os.path.join(args.seq, "colour", name))[..., :3].astype(np.float64)
        ui, ri = u[inside].astype(int), r[inside].astype(int)
        seen = np.zeros(len(site), bool)
        seen[inside] = np.abs(depth[ri, ui] - z[inside]) < VISIBLE_TOLERANCE_M
        s = np.full((len(site), 3), np.nan)
        idx = np.nonzero(seen)[0]
        s[idx] = colour[r[idx].astype(int), u[idx].astype(int)]
        samples.append(s)
    with warnings.catch_warnings():  # points no frame sees: all NaN, left out below
        warnings.simplefilter("ignore", RuntimeWarning)
        ref = np.nanmedian(np.stack(samples), axis=0)
    ok = np.all(np.isfinite(ref), axis=1)
    ref, got = ref[ok], rgb[ok]
    d = got - ref
    out = {
        "points_compared": int(ok.sum()),
        "rms_levels": float(np.sqrt(np.mean(d ** 2))),
        "median_abs_levels": float(np.median(np.max(np.abs(d), axis=1))),
        "grey_rms_levels": float(np.sqrt(np.mean((128.0 - ref) ** 2))),
        "mean_rms_levels": float(np.sqrt(np.mean((ref.mean(axis=0) - ref) ** 2))),
        "grey_share": float(np.mean(np.all(got == 128, axis=1))),
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
