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

Next to the tangent plane, the 3D distance to the truth surface (`*_3d_mm`): the
nearest of samples of the bilinear truth surface 1 mm apart, with the steep ramps
between samples (trench sides, wall faces) filled in 1 mm steps, so that a point on a
vertical face is measured against that face and not against the floor beside it (the
tangent plane of a height field at a wall's foot or top is the floor's or the top's,
and calls a correct point on the face an outlier of up to the wall's height). Its
resolution is about 0.5 mm.

Prints one JSON object, for the points over the trench rectangle of site.json
("trench") and for all the points over the truth raster:
  points, median_mm, p95_mm, p99_mm, max_mm, share_over_10mm_pct, share_over_25mm_pct,
  median_3d_mm, p95_3d_mm, p99_3d_mm, share_over_10mm_3d_pct
and the vertical |z - h| median and p95 for comparison.

Needs the Debian python3-gdal, python3-numpy and python3-scipy (run it with /usr/bin/python3).
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


def distances_3d(xyz, h, gt, step=0.001):
    """Distance of each point to the bilinear truth surface, from samples `step` apart
    in x and y, plus samples every `step` in z along the steep edges between them."""
    from scipy.spatial import cKDTree
    x0, dx, _, y0, _, dy = gt
    rows, cols = h.shape
    lo = xyz.min(axis=0) - 0.02
    hi = xyz.max(axis=0) + 0.02
    # Sample positions in pixel coordinates (column, row) over the points' box.
    c_lo, c_hi = sorted([(lo[0] - x0) / dx - 0.5, (hi[0] - x0) / dx - 0.5])
    r_lo, r_hi = sorted([(lo[1] - y0) / dy - 0.5, (hi[1] - y0) / dy - 0.5])
    c_lo, r_lo = max(c_lo, 0.0), max(r_lo, 0.0)
    c_hi, r_hi = min(c_hi, cols - 1.001), min(r_hi, rows - 1.001)
    fc = np.arange(c_lo, c_hi, step / abs(dx))
    fr = np.arange(r_lo, r_hi, step / abs(dy))
    FC, FR = np.meshgrid(fc, fr)
    c0 = np.floor(FC).astype(int)
    r0 = np.floor(FR).astype(int)
    tc, tr = FC - c0, FR - r0
    z = ((1 - tr) * ((1 - tc) * h[r0, c0] + tc * h[r0, c0 + 1]) +
         tr * ((1 - tc) * h[r0 + 1, c0] + tc * h[r0 + 1, c0 + 1]))
    X = x0 + (FC + 0.5) * dx
    Y = y0 + (FR + 0.5) * dy
    samples = [np.stack([X.ravel(), Y.ravel(), z.ravel()], axis=1)]
    # Fill the ramps: between each sample and its right and lower neighbour, points
    # every `step` in z where the two differ by more than `step`.
    for axis in (0, 1):
        za = z[:, :-1] if axis == 1 else z[:-1, :]
        zb = z[:, 1:] if axis == 1 else z[1:, :]
        xa = X[:, :-1] if axis == 1 else X[:-1, :]
        xb = X[:, 1:] if axis == 1 else X[1:, :]
        ya = Y[:, :-1] if axis == 1 else Y[:-1, :]
        yb = Y[:, 1:] if axis == 1 else Y[1:, :]
        steep = np.abs(zb - za) > step
        if not steep.any():
            continue
        za, zb, xa, xb, ya, yb = (a[steep] for a in (za, zb, xa, xb, ya, yb))
        n = np.ceil(np.abs(zb - za) / step).astype(int)
        k = np.repeat(np.arange(n.size), n)
        t = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n) + 0.5) / np.repeat(n, n)
        samples.append(np.stack([xa[k] + t * (xb[k] - xa[k]), ya[k] + t * (yb[k] - ya[k]),
                                 za[k] + t * (zb[k] - za[k])], axis=1))
    pts = np.concatenate(samples)
    pts = pts[np.isfinite(pts[:, 2])]
    d, _ = cKDTree(pts).query(xyz, workers=-1)
    return d


def stats(normal, vertical, d3=None):
    if normal.size == 0:
        return {"points": 0}
    mm = normal * 1e3
    extra = {}
    if d3 is not None:
        m3 = d3 * 1e3
        extra = {"median_3d_mm": round(float(np.median(m3)), 3),
                 "p95_3d_mm": round(float(np.percentile(m3, 95)), 3),
                 "p99_3d_mm": round(float(np.percentile(m3, 99)), 3),
                 "share_over_10mm_3d_pct": round(float(100 * np.mean(m3 > 10)), 3)}
    return {"points": int(mm.size),
            "median_mm": round(float(np.median(mm)), 3),
            "p95_mm": round(float(np.percentile(mm, 95)), 3),
            "p99_mm": round(float(np.percentile(mm, 99)), 3),
            "max_mm": round(float(mm.max()), 1),
            "share_over_10mm_pct": round(float(100 * np.mean(mm > 10)), 3),
            "share_over_25mm_pct": round(float(100 * np.mean(mm > 25)), 3),
            "vertical_median_mm": round(float(np.median(vertical) * 1e3), 3),
            "vertical_p95_mm": round(float(np.percentile(vertical, 95) * 1e3), 3), **extra}


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
    d3 = distances_3d(p, h, gt)
    in_trench = (p[:, 0] >= t["min_E"]) & (p[:, 0] <= t["max_E"]) & (p[:, 1] >= t["min_N"]) & (p[:, 1] <= t["max_N"])
    out = {"points_total": int(xyz.shape[0]),
           "trench": stats(normal[in_trench], vertical[in_trench], d3[in_trench]),
           "over_truth": stats(normal, vertical, d3)}
    text = json.dumps(out, indent=1)
    print(text)
    if a.json_out:
        with open(a.json_out, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
