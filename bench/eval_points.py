#!/usr/bin/python3
"""Accuracy of a layer's dense point cloud against the synthetic truth surface.

Usage: eval_points.py POINTS.ply TRUTH_surface.tif SITE.json [--json-out FILE]

POINTS.ply is the `points` product of the dense stage (binary little-endian PLY,
float or double x y z, site CRS or site frame with a `comment strata_offset E N Z`
line). The truth is a height field (the synthetic ground, 5 mm cells); for each
point over it the distance to the truth is measured along the local normal of the
truth surface: |z - h(x, y)| / sqrt(1 + |grad h|^2), h bilinear and its gradient
from central differences, which is the distance to the tangent plane (exact on a
plane, and on steep walls not inflated the way a vertical difference is).

Prints one JSON object, for the points over the trench rectangle of site.json
("trench") and for all the points over the truth raster:
  points, median_mm, p95_mm, p99_mm, max_mm, share_over_10mm_pct, share_over_25mm_pct
and the vertical |z - h| median and p95 for comparison.

Needs the Debian python3-gdal and python3-numpy (run it with /usr/bin/python3).
"""
import argparse
import json
import re
import sys

import numpy as np
from osgeo import gdal

gdal.UseExceptions()

PLY_TYPES = {"float": "<f4", "double": "<f8", "uchar": "u1", "uint8": "u1", "int": "<i4", "uint": "<u4",
             "short": "<i2", "ushort": "<u2", "float32": "<f4", "float64": "<f8", "int32": "<i4"}


def read_ply_points(path):
    with open(path, "rb") as f:
        header = []
        while True:
            line = f.readline()
            if not line:
                sys.exit(f"eval_points: {path}: no end_header")
            line = line.decode("ascii", "replace").strip()
            header.append(line)
            if line == "end_header":
                break
        if "format binary_little_endian 1.0" not in header:
            sys.exit(f"eval_points: {path}: only binary little-endian PLY is read")
        offset = np.zeros(3)
        count, fields, in_vertex = 0, [], False
        for line in header:
            m = re.match(r"comment strata_offset (\S+) (\S+) (\S+)", line)
            if m:
                offset = np.array([float(v) for v in m.groups()])
            parts = line.split()
            if parts[:2] == ["element", "vertex"]:
                count, in_vertex = int(parts[2]), True
            elif parts and parts[0] == "element":
                in_vertex = False
            elif in_vertex and parts[0] == "property":
                if parts[1] == "list":
                    sys.exit(f"eval_points: {path}: list property in the vertex element")
                fields.append((parts[2], PLY_TYPES[parts[1]]))
        data = np.fromfile(f, dtype=np.dtype(fields), count=count)
    xyz = np.stack([data["x"], data["y"], data["z"]], axis=1).astype(np.float64)
    return xyz + offset


def truth_surface(path):
    ds = gdal.Open(path)
    gt = ds.GetGeoTransform()
    band = ds.GetRasterBand(1)
    h = band.ReadAsArray().astype(np.float64)
    nodata = band.GetNoDataValue()
    if nodata is not None:
        h[h == nodata] = np.nan
    return h, gt


def distances(xyz, h, gt):
    # Pixel-centre coordinates: column c centre at x0 + (c + 0.5) dx.
    x0, dx, _, y0, _, dy = gt
    fc = (xyz[:, 0] - x0) / dx - 0.5
    fr = (xyz[:, 1] - y0) / dy - 0.5
    rows, cols = h.shape
    inside = (fc >= 0) & (fr >= 0) & (fc < cols - 1) & (fr < rows - 1)
    c0 = np.floor(fc[inside]).astype(int)
    r0 = np.floor(fr[inside]).astype(int)
    tc = fc[inside] - c0
    tr = fr[inside] - r0
    gy, gx = np.gradient(h, abs(dy), dx)  # rows run south when dy < 0
    if dy < 0:
        gy = -gy

    def bilinear(a):
        return ((1 - tr) * ((1 - tc) * a[r0, c0] + tc * a[r0, c0 + 1]) +
                tr * ((1 - tc) * a[r0 + 1, c0] + tc * a[r0 + 1, c0 + 1]))

    z = bilinear(h)
    slope2 = bilinear(gx) ** 2 + bilinear(gy) ** 2
    dz = xyz[inside, 2] - z
    ok = np.isfinite(dz) & np.isfinite(slope2)
    normal = np.abs(dz[ok]) / np.sqrt(1 + slope2[ok])
    idx = np.nonzero(inside)[0][ok]
    return idx, normal, np.abs(dz[ok])


def stats(normal, vertical):
    if normal.size == 0:
        return {"points": 0}
    mm = normal * 1e3
    return {"points": int(mm.size),
            "median_mm": round(float(np.median(mm)), 3),
            "p95_mm": round(float(np.percentile(mm, 95)), 3),
            "p99_mm": round(float(np.percentile(mm, 99)), 3),
            "max_mm": round(float(mm.max()), 1),
            "share_over_10mm_pct": round(float(100 * np.mean(mm > 10)), 3),
            "share_over_25mm_pct": round(float(100 * np.mean(mm > 25)), 3),
            "vertical_median_mm": round(float(np.median(vertical) * 1e3), 3),
            "vertical_p95_mm": round(float(np.percentile(vertical, 95) * 1e3), 3)}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("points")
    ap.add_argument("truth")
    ap.add_argument("site")
    ap.add_argument("--json-out")
    a = ap.parse_args()
    xyz = read_ply_points(a.points)
    h, gt = truth_surface(a.truth)
    idx, normal, vertical = distances(xyz, h, gt)
    with open(a.site) as f:
        t = json.load(f)["trench"]
    p = xyz[idx]
    in_trench = (p[:, 0] >= t["min_E"]) & (p[:, 0] <= t["max_E"]) & (p[:, 1] >= t["min_N"]) & (p[:, 1] <= t["max_N"])
    out = {"points_total": int(xyz.shape[0]),
           "trench": stats(normal[in_trench], vertical[in_trench]),
           "over_truth": stats(normal, vertical)}
    text = json.dumps(out, indent=1)
    print(text)
    if a.json_out:
        with open(a.json_out, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
