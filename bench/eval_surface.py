#!/usr/bin/python3
"""Accuracy and completeness of a layer DTM against the synthetic truth surface.

Usage: eval_surface.py DTM.tif TRUTH_surface.tif SITE.json [--png PREFIX]

The DTM is resampled (bilinear, GDAL warp) onto the truth grid; both are then
cropped to the trench rectangle of site.json ("trench": min_E, min_N, max_E,
max_N). Every truth cell inside the trench counts; a cell whose DTM value is
nodata counts as not reconstructed.

Prints one JSON object:
  median_abs_mm, p95_abs_mm   |DTM - truth| over the reconstructed trench cells
  median_signed_mm            median of DTM - truth (bias; positive = DTM too high)
  completeness_pct            reconstructed / all trench cells, percent
  cells                       trench cells (truth grid)
With --png PREFIX it also writes PREFIX_error.png (|error| 0..20 mm, black = none)
for a quick look.

Needs the Debian python3-gdal and python3-numpy (run it with /usr/bin/python3).
"""
import argparse
import json
import sys

import numpy as np
from osgeo import gdal

gdal.UseExceptions()


def trench_bounds(site_json):
    with open(site_json) as f:
        site = json.load(f)
    t = site["trench"]
    return t["min_E"], t["min_N"], t["max_E"], t["max_N"]


def read_band(ds):
    band = ds.GetRasterBand(1)
    a = band.ReadAsArray().astype(np.float64)
    nd = band.GetNoDataValue()
    if nd is not None:
        a[a == nd] = np.nan
    a[~np.isfinite(a)] = np.nan
    return a


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dtm")
    ap.add_argument("truth")
    ap.add_argument("site_json")
    ap.add_argument("--png", help="write PREFIX_error.png")
    args = ap.parse_args()

    truth_ds = gdal.Open(args.truth)
    gt = truth_ds.GetGeoTransform()
    if gt[2] != 0 or gt[4] != 0:
        sys.exit(f"eval_surface: {args.truth}: rotated rasters are not supported")
    w, h = truth_ds.RasterXSize, truth_ds.RasterYSize
    x0, y1 = gt[0], gt[3]
    x1, y0 = x0 + w * gt[1], y1 + h * gt[5]
    truth = read_band(truth_ds)

    # DTM onto the truth grid: bilinear, nodata stays nodata (no filling).
    warped = gdal.Warp("", args.dtm, format="MEM", outputBounds=(x0, y0, x1, y1), width=w, height=h,
                       resampleAlg="bilinear", dstNodata=-9999.0, srcNodata=None,
                       dstSRS=truth_ds.GetProjection())
    dtm = read_band(warped)

    e_min, n_min, e_max, n_max = trench_bounds(args.site_json)
    xs = x0 + (np.arange(w) + 0.5) * gt[1]
    ys = y1 + (np.arange(h) + 0.5) * gt[5]
    in_x = (xs >= e_min) & (xs <= e_max)
    in_y = (ys >= n_min) & (ys <= n_max)
    mask = np.outer(in_y, in_x) & np.isfinite(truth)
    cells = int(mask.sum())
    if cells == 0:
        sys.exit("eval_surface: the trench does not overlap the truth raster")
    have = mask & np.isfinite(dtm)
    err = (dtm - truth)[have]
    out = {
        "median_abs_mm": float(np.median(np.abs(err)) * 1e3) if err.size else None,
        "p95_abs_mm": float(np.percentile(np.abs(err), 95) * 1e3) if err.size else None,
        "median_signed_mm": float(np.median(err) * 1e3) if err.size else None,
        "completeness_pct": 100.0 * float(have.sum()) / cells,
        "cells": cells,
    }
    print(json.dumps(out))

    if args.png:
        img = np.zeros((h, w), dtype=np.uint8)
        e = np.abs(dtm - truth)
        img[have] = np.clip(55 + 200 * e[have] / 0.02, 55, 255).astype(np.uint8)
        img[mask & ~have] = 0
        img[~mask] = 30
        drv = gdal.GetDriverByName("MEM")
        m = drv.Create("", w, h, 1, gdal.GDT_Byte)
        m.GetRasterBand(1).WriteArray(img)
        gdal.GetDriverByName("PNG").CreateCopy(args.png + "_error.png", m)


if __name__ == "__main__":
    main()
