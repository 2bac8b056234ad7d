#!/usr/bin/python3
"""Completeness of layer DTMs where photos are weak: the steep trench sides and the
sheltered ground at the foot of walls and between the wall stones.

Usage: eval_regions.py TRUTH_surface.tif SITE.json NAME=DTM.tif [NAME=DTM.tif ...]

Regions, from the truth surface alone (cells inside the trench of site.json):
  steep      slope over 45 degrees (trench sides, stone faces, pit sides)
  sheltered  not steep, but within 5 cm of ground standing at least 5 cm higher
             (the foot of the trench sides, gaps between the wall stones)
  other      the rest of the trench
Each DTM is resampled onto the truth grid as eval_surface.py does; a cell counts as
complete where the DTM has a value. Prints one JSON object: per DTM and region the
completeness (percent), the median and p95 |DTM - truth| (mm) and the cell count.
"""
import json
import os
import sys

import numpy as np
from osgeo import gdal

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from eval_surface import read_band, trench_bounds  # noqa: E402

gdal.UseExceptions()

STEEP_SLOPE = 1.0        # tan(45 degrees)
SHELTER_RADIUS_M = 0.05  # metres
SHELTER_RISE_M = 0.05    # metres


def local_max(a, r):
    """Maximum over a (2r+1)^2 window, NaN ignored (as -inf)."""
    b = np.where(np.isfinite(a), a, -np.inf)
    out = b.copy()
    h, w = b.shape
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            if dx * dx + dy * dy > r * r:
                continue
            shifted = np.full_like(b, -np.inf)
            ys, yd = (slice(dy, h), slice(0, h - dy)) if dy >= 0 else (slice(0, h + dy), slice(-dy, h))
            xs, xd = (slice(dx, w), slice(0, w - dx)) if dx >= 0 else (slice(0, w + dx), slice(-dx, w))
            shifted[yd, xd] = b[ys, xs]
            out = np.maximum(out, shifted)
    return out


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    truth_path, site_json = sys.argv[1], sys.argv[2]
    truth_ds = gdal.Open(truth_path)
    gt = truth_ds.GetGeoTransform()
    w, h = truth_ds.RasterXSize, truth_ds.RasterYSize
    x0, y1, cell = gt[0], gt[3], gt[1]
    x1, y0 = x0 + w * gt[1], y1 + h * gt[5]
    truth = read_band(truth_ds)
    e_min, n_min, e_max, n_max = trench_bounds(site_json)
    xs = x0 + (np.arange(w) + 0.5) * gt[1]
    ys = y1 + (np.arange(h) + 0.5) * gt[5]
    trench = np.outer((ys >= n_min) & (ys <= n_max), (xs >= e_min) & (xs <= e_max)) & np.isfinite(truth)
    gy, gx = np.gradient(truth, cell)
    slope = np.hypot(gx, gy)
    steep = trench & (slope > STEEP_SLOPE)
    higher = local_max(truth, int(round(SHELTER_RADIUS_M / cell))) - truth
    sheltered = trench & ~steep & (higher >= SHELTER_RISE_M)
    other = trench & ~steep & ~sheltered
    regions = {"steep": steep, "sheltered": sheltered, "other": other, "trench": trench}

    out = {"regions": {k: int(v.sum()) for k, v in regions.items()}, "dtms": {}}
    for arg in sys.argv[3:]:
        name, path = arg.split("=", 1)
        warped = gdal.Warp("", path, format="MEM", outputBounds=(x0, y0, x1, y1), width=w, height=h,
                           resampleAlg="bilinear", dstNodata=-9999.0, dstSRS=truth_ds.GetProjection())
        dtm = read_band(warped)
        res = {}
        for k, m in regions.items():
            have = m & np.isfinite(dtm)
            err = np.abs(dtm - truth)[have]
            res[k] = {
                "completeness_pct": 100.0 * float(have.sum()) / max(int(m.sum()), 1),
                "median_abs_mm": float(np.median(err) * 1e3) if err.size else None,
                "p95_abs_mm": float(np.percentile(err, 95) * 1e3) if err.size else None,
            }
        out["dtms"][name] = res
    print(json.dumps(out))


if __name__ == "__main__":
    main()
