#!/usr/bin/python3
"""Signed error of each layer DTM against the synthetic truth surface (docs/volume.md).

Usage: eval_dtm_bias.py [--project DIR] [--data DIR] [--outline FILE]
                        [--layers L1,L2,...] [--out FILE.json] [--note TEXT]

For every layer whose products/<L>/dtm.tif exists in the project, the truth
surface data/truth/<L>/surface.tif is sampled bilinearly at the DTM's cell
centres (both EPSG:32636; the pixel offset between the grids is reported, and is
whole cells on the synthetic example, so the sampling is exact there) and
e = DTM - truth (mm, positive = DTM too high) is summarised:

  - inside / outside the trench outline (GeoJSON, first polygon),
  - inside: by the true surface's slope (np.gradient of the truth raster), by
    distance to the outline (the trench wall), by depth below the ground
    (truth L1 - truth L, m),
  - measured cells (dtm_sigma finite) vs cells the DTM filled (fill_small_gaps
    in src/products/dtm.cpp writes a height but no sigma) vs cells with no DTM,
  - e / dtm_sigma inside / outside, and by stated-sigma bins,
  - a least-squares fit e = a + tilt + shift . grad(truth) on measured cells
    (offset, tilt and horizontal shift of the DTM: a georeference signature),
  - for consecutive layers that both have a DTM, the thickness error
    (DTM_k - DTM_k+1) - (truth_k - truth_k+1) over cells inside the outline where
    the truth thickness exceeds 5 mm, as a volume error (m3, % of
    truth/units.csv), and the same difference on the ground outside the trench.
  - independent of any DTM: the truth rasters' own volume per unit against
    truth/units.csv (the truth's rasterisation).

Statistics: n, mean, median, NMAD (1.4826 x MAD), p5, p95 in mm. Cells where
|e| > 50 mm are counted separately ("gross") and also kept in the mean.

Needs the Debian python3-gdal and python3-numpy (run with /usr/bin/python3).
"""
import argparse
import datetime
import json
import math
import os
import sys

import numpy as np
from osgeo import gdal

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import eval_surface  # noqa: E402  (bench/eval_surface.py: read_band)

gdal.UseExceptions()


def read(path):
    ds = gdal.Open(path)
    gt = ds.GetGeoTransform()
    if gt[2] != 0 or gt[4] != 0 or gt[5] >= 0:
        sys.exit(f"eval_dtm_bias: {path}: only north-up rasters")
    a = eval_surface.read_band(ds)
    srs = ds.GetSpatialRef()
    epsg = srs.GetAuthorityCode(None) if srs is not None else None
    return a, gt, epsg


def centres(gt, shape):
    rows, cols = shape
    x = gt[0] + (np.arange(cols) + 0.5) * gt[1]
    y = gt[3] + (np.arange(rows) + 0.5) * gt[5]
    return x, y


def bilinear(src, sgt, x, y):
    """src sampled at the points (x[j], y[i]) of a grid; NaN where any of the four
    neighbours is NaN or outside."""
    u = (x - sgt[0]) / sgt[1] - 0.5  # column coordinate, 0 at the first centre
    v = (y - sgt[3]) / sgt[5] - 0.5
    rows, cols = src.shape
    c0 = np.floor(u).astype(np.int64)
    r0 = np.floor(v).astype(np.int64)
    fu = u - c0
    fv = v - r0
    # exact grid coincidence: avoid needing the +1 neighbour
    fu[np.abs(fu) < 1e-6] = 0.0
    fv[np.abs(fv) < 1e-6] = 0.0
    out = np.full((len(y), len(x)), np.nan)
    cok = (c0 >= 0) & (c0 + (fu > 0) < cols)
    rok = (r0 >= 0) & (r0 + (fv > 0) < rows)
    ci = np.where(cok)[0]
    ri = np.where(rok)[0]
    if len(ci) == 0 or len(ri) == 0:
        return out, (float("nan"), float("nan"))
    C0 = c0[ci]
    C1 = np.minimum(C0 + 1, cols - 1)
    R0 = r0[ri]
    R1 = np.minimum(R0 + 1, rows - 1)
    FU = fu[ci][None, :]
    FV = fv[ri][:, None]
    z00 = src[np.ix_(R0, C0)]
    z01 = src[np.ix_(R0, C1)]
    z10 = src[np.ix_(R1, C0)]
    z11 = src[np.ix_(R1, C1)]
    # weights of zero must not propagate NaN from an unused neighbour
    w00 = (1 - FU) * (1 - FV)
    w01 = FU * (1 - FV)
    w10 = (1 - FU) * FV
    w11 = FU * FV
    acc = np.zeros_like(w00 * z00)
    bad = np.zeros(acc.shape, bool)
    for w, z in ((w00, z00), (w01, z01), (w10, z10), (w11, z11)):
        w = np.broadcast_to(w, acc.shape)
        used = w > 0
        bad |= used & ~np.isfinite(z)
        acc += np.where(used, w * np.nan_to_num(z), 0.0)
    acc[bad] = np.nan
    out[np.ix_(ri, ci)] = acc
    return out, (float(u[0] - round(u[0])), float(v[0] - round(v[0])))


def read_outline(path):
    with open(path) as f:
        g = json.load(f)
    if g.get("type") == "FeatureCollection":
        g = g["features"][0]
    if g.get("type") == "Feature":
        g = g["geometry"]
    if g["type"] == "Polygon":
        ring = g["coordinates"][0]
    elif g["type"] == "MultiPolygon":
        ring = g["coordinates"][0][0]
    else:
        sys.exit(f"eval_dtm_bias: {path}: no polygon")
    return np.array([(p[0], p[1]) for p in ring], float)


def inside_and_distance(ring, x, y):
    X, Y = np.meshgrid(x, y)
    inside = np.zeros(X.shape, bool)
    dist = np.full(X.shape, np.inf)
    n = len(ring) - 1 if np.allclose(ring[0], ring[-1]) else len(ring)
    for k in range(n):
        x1, y1 = ring[k]
        x2, y2 = ring[(k + 1) % len(ring)]
        cond = (y1 > Y) != (y2 > Y)
        with np.errstate(divide="ignore", invalid="ignore"):
            xi = x1 + (Y - y1) * (x2 - x1) / (y2 - y1)
        inside ^= cond & (X < xi)
        dx, dy = x2 - x1, y2 - y1
        L2 = dx * dx + dy * dy
        t = np.clip(((X - x1) * dx + (Y - y1) * dy) / L2, 0, 1) if L2 > 0 else 0
        d = np.hypot(X - (x1 + t * dx), Y - (y1 + t * dy))
        dist = np.minimum(dist, d)
    return inside, dist


def stats_mm(e, gross_mm=50.0):
    """e in metres -> dict in mm."""
    e = e[np.isfinite(e)] * 1000.0
    n = int(e.size)
    if n == 0:
        return {"n": 0}
    med = float(np.median(e))
    nmad = float(1.4826 * np.median(np.abs(e - med)))
    p5, p95 = np.percentile(e, [5, 95])
    good = e[np.abs(e) <= gross_mm]
    return {
        "n": n,
        "median_mm": round(med, 4),
        "mean_mm": round(float(e.mean()), 4),
        "nmad_mm": round(nmad, 4),
        "p5_mm": round(float(p5), 4),
        "p95_mm": round(float(p95), 4),
        "gross_n": int(n - good.size),
        "mean_without_gross_mm": round(float(good.mean()), 4) if good.size else None,
    }


def z_stats(z):
    z = z[np.isfinite(z)]
    if z.size == 0:
        return {"n": 0}
    med = float(np.median(z))
    return {
        "n": int(z.size),
        "median": round(med, 4),
        "nmad": round(float(1.4826 * np.median(np.abs(z - med))), 4),
        "std": round(float(z.std()), 4),
        "frac_abs_lt_1": round(float(np.mean(np.abs(z) < 1)), 4),
        "frac_abs_lt_1.96": round(float(np.mean(np.abs(z) < 1.96)), 4),
    }


def binned(e, key, edges, mask, label="{}-{}"):
    out = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        m = mask & (key >= lo) & (key < hi)
        s = stats_mm(e[m])
        s["bin"] = label.format(lo, hi)
        out.append(s)
    return out


def laplacian(z, h, cell):
    """5-point Laplacian of z with a step of h cells (1/m)."""
    lap = np.full(z.shape, np.nan)
    lap[h:-h, h:-h] = (z[2 * h:, h:-h] + z[:-2 * h, h:-h] + z[h:-h, 2 * h:] + z[h:-h, :-2 * h]
                       - 4 * z[h:-h, h:-h]) / (h * cell) ** 2
    return lap


def gauss_smooth(z, s_cells, pad=100):
    """Isotropic Gaussian of s_cells per axis (FFT, edge-padded)."""
    zz = np.pad(np.where(np.isfinite(z), z, np.nanmean(z)), pad, mode="edge")
    ny, nx = zz.shape
    ky = np.fft.fftfreq(ny)[:, None]
    kx = np.fft.rfftfreq(nx)[None, :]
    H = np.exp(-2 * (np.pi ** 2) * (s_cells ** 2) * (kx ** 2 + ky ** 2))
    return np.fft.irfft2(np.fft.rfft2(zz) * H, s=zz.shape)[pad:-pad, pad:-pad]


def fit_shift(e, gx, gy, X, Y, mask, iters=3):
    """e ~ a + bx (X-Xc) + by (Y-Yc) + sx gx + sy gy, robust by trimming at 4 NMAD.
    A DTM displaced by s (dtm(p) = truth(p + s)) gives e = s . grad."""
    m = mask & np.isfinite(e) & np.isfinite(gx) & np.isfinite(gy)
    if m.sum() < 100:
        return None
    ev, gxv, gyv = e[m], gx[m], gy[m]
    xv, yv = X[m] - X[m].mean(), Y[m] - Y[m].mean()
    A = np.column_stack([np.ones_like(ev), xv, yv, gxv, gyv])
    keep = np.ones(ev.size, bool)
    for _ in range(iters):
        sol, *_ = np.linalg.lstsq(A[keep], ev[keep], rcond=None)
        r = ev - A @ sol
        med = np.median(r[keep])
        nmad = 1.4826 * np.median(np.abs(r[keep] - med))
        keep = np.abs(r - med) < 4 * max(nmad, 1e-5)
    return {
        "n": int(keep.sum()),
        "offset_mm": round(float(sol[0]) * 1000, 4),
        "tilt_x_mm_per_m": round(float(sol[1]) * 1000, 4),
        "tilt_y_mm_per_m": round(float(sol[2]) * 1000, 4),
        "shift_e_mm": round(float(sol[3]) * 1000, 4),
        "shift_n_mm": round(float(sol[4]) * 1000, 4),
        "residual_nmad_mm": round(float(nmad) * 1000, 4),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    root = os.path.dirname(HERE)
    ap.add_argument("--project", default=os.path.join(root, "example", "site-full"))
    ap.add_argument("--data", default=os.path.join(root, "example", "data-full"))
    ap.add_argument("--outline", help="default: PROJECT/trench_outline.geojson, else DATA/trench_outline.geojson")
    ap.add_argument("--layers", default="L1,L2,L3,L4")
    ap.add_argument("--min-thickness", type=float, default=0.005)
    ap.add_argument("--out")
    ap.add_argument("--note", help="free text stored in the JSON (provenance of the run)")
    args = ap.parse_args()

    layers = args.layers.split(",")
    outline = args.outline
    if not outline:
        for c in (os.path.join(args.project, "trench_outline.geojson"), os.path.join(args.data, "trench_outline.geojson")):
            if os.path.exists(c):
                outline = c
                break
    ring = read_outline(outline)

    # Truth rasters (all layers share one grid on the generator's output).
    truth = {}
    for L in layers:
        p = os.path.join(args.data, "truth", L, "surface.tif")
        if os.path.exists(p):
            truth[L] = read(p)
    if not truth:
        sys.exit("eval_dtm_bias: no truth rasters")
    tgt = truth[layers[0]][1]
    cell_t = tgt[1]

    units = {}
    up = os.path.join(args.data, "truth", "units.csv")
    if os.path.exists(up):
        with open(up) as f:
            hdr = f.readline().strip().split(",")
            for line in f:
                v = dict(zip(hdr, line.strip().split(",")))
                units[v["unit"]] = {k: float(x) for k, x in v.items() if k != "unit"}
    layer_unit = {}
    lp = os.path.join(args.data, "layers.csv")
    if os.path.exists(lp):
        with open(lp) as f:
            hdr = f.readline().strip().split(",")
            for line in f:
                v = dict(zip(hdr, line.strip().split(",")))
                layer_unit[v["layer"]] = v["unit"]

    result = {
        "generated_utc": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "project": os.path.abspath(args.project),
        "data": os.path.abspath(args.data),
        "outline": os.path.abspath(outline),
        "error_sign": "DTM - truth (positive = DTM too high)",
        "note": args.note,
        "layers": {},
        "missing_layers": [],
        "truth_rasterisation": [],
        "inter_layer": [],
    }

    # The truth's own rasterisation: volume of each unit summed over the truth
    # raster's cells against truth/units.csv (the generator's exact integral).
    tx, ty = centres(tgt, truth[layers[0]][0].shape)
    t_in, t_dist = inside_and_distance(ring, tx, ty)
    for a, b in zip(layers[:-1], layers[1:]):
        if a not in truth or b not in truth:
            continue
        u = layer_unit.get(a)
        d = truth[a][0] - truth[b][0]
        area = cell_t * cell_t
        rec = {
            "unit": u,
            "layers": f"{a}-{b}",
            "raster_volume_all_cells_m3": float(np.nansum(d) * area),
            "raster_volume_in_outline_m3": float(np.nansum(d[t_in]) * area),
            "raster_volume_gt_5mm_m3": float(np.nansum(d[d > args.min_thickness]) * area),
            "raster_volume_gt_1mm_m3": float(np.nansum(d[d > 0.001]) * area),
            "raster_area_gt_1mm_m2": float(np.sum(d > 0.001) * area),
            "raster_negative_volume_m3": float(np.nansum(d[d < 0]) * area),
            "dug_outside_outline_m3": float(np.nansum(d[(~t_in) & (d > 0.001)]) * area),
        }
        if u in units:
            tv = units[u]["volume_m3"]
            rec["units_csv_volume_m3"] = tv
            rec["raster_vs_units_csv_pct"] = 100 * (rec["raster_volume_all_cells_m3"] - tv) / tv
            rec["raster_gt_5mm_vs_units_csv_pct"] = 100 * (rec["raster_volume_gt_5mm_m3"] - tv) / tv
            rec["units_csv_area_m2"] = units[u]["area_m2"]
        result["truth_rasterisation"].append(rec)

    # Per layer.
    grid = None  # the DTM grid of the first layer found: later ones must match
    E = {}
    grid_of = {}
    D = {}
    T = {}
    for L in layers:
        dp = os.path.join(args.project, "products", L, "dtm.tif")
        sp = os.path.join(args.project, "products", L, "dtm_sigma.tif")
        if not os.path.exists(dp) or L not in truth:
            result["missing_layers"].append(
                {"layer": L, "dtm": dp, "dtm_exists": os.path.exists(dp), "truth_exists": L in truth}
            )
            continue
        dtm, dgt, depsg = read(dp)
        sig = read(sp)[0] if os.path.exists(sp) else np.full(dtm.shape, np.nan)
        tr, tgt_l, tepsg = truth[L]
        if depsg != tepsg:
            sys.exit(f"eval_dtm_bias: {L}: DTM EPSG {depsg} != truth EPSG {tepsg}")
        x, y = centres(dgt, dtm.shape)
        # crop the DTM grid to the truth extent
        t_w, t_n = tgt_l[0], tgt_l[3]
        t_e = t_w + tr.shape[1] * tgt_l[1]
        t_s = t_n + tr.shape[0] * tgt_l[5]
        cj = np.where((x > t_w) & (x < t_e))[0]
        ri = np.where((y < t_n) & (y > t_s))[0]
        x, y = x[cj], y[ri]
        dtm = dtm[np.ix_(ri, cj)]
        sig = sig[np.ix_(ri, cj)]
        ts, frac = bilinear(tr, tgt_l, x, y)
        ground, _ = bilinear(truth[layers[0]][0], truth[layers[0]][1], x, y)
        X, Y = np.meshgrid(x, y)
        inside, dist = inside_and_distance(ring, x, y)
        gy_, gx_ = np.gradient(ts, dgt[5], dgt[1])  # rows run north to south
        slope = np.degrees(np.arctan(np.hypot(gx_, gy_)))
        depth = ground - ts
        e = dtm - ts
        measured = np.isfinite(dtm) & np.isfinite(sig)
        filled = np.isfinite(dtm) & ~np.isfinite(sig)
        nodtm = ~np.isfinite(dtm) & np.isfinite(ts)
        valid = np.isfinite(e)
        outside = ~inside

        rec = {
            "dtm": dp,
            "dtm_geotransform": list(dgt),
            "truth_geotransform": list(tgt_l),
            "truth_sample_fraction_col_row": frac,
            "epsg": depsg,
            "cells_compared": int(valid.sum()),
            "inside": stats_mm(e[inside & valid]),
            "outside": stats_mm(e[outside & valid]),
            "inside_measured": stats_mm(e[inside & measured]),
            "inside_filled": stats_mm(e[inside & filled]),
            "outside_measured": stats_mm(e[outside & measured]),
            "outside_filled": stats_mm(e[outside & filled]),
            "cells": {
                "inside_measured": int((inside & measured & np.isfinite(ts)).sum()),
                "inside_filled": int((inside & filled & np.isfinite(ts)).sum()),
                "inside_no_dtm": int((inside & nodtm).sum()),
                "outside_measured": int((outside & measured & np.isfinite(ts)).sum()),
                "outside_filled": int((outside & filled & np.isfinite(ts)).sum()),
                "outside_no_dtm": int((outside & nodtm).sum()),
            },
            "inside_by_slope_deg": binned(e, slope, [0, 10, 30, 60, 90.01], inside & valid),
            "inside_measured_by_slope_deg": binned(e, slope, [0, 10, 30, 60, 90.01], inside & measured),
            "outside_by_slope_deg": binned(e, slope, [0, 10, 30, 60, 90.01], outside & valid),
            "inside_by_wall_distance_m": binned(
                e, dist, [0, 0.02, 0.05, 0.1, 0.2, 0.5, 10], inside & valid
            ),
            "inside_by_depth_below_ground_m": binned(
                e, depth, [-1, 0.005, 0.1, 0.2, 0.3, 0.4, 0.5, 2], inside & valid
            ),
            "inside_measured_by_depth_below_ground_m": binned(
                e, depth, [-1, 0.005, 0.1, 0.2, 0.3, 0.4, 0.5, 2], inside & measured
            ),
            "inside_flat_measured_by_depth_below_ground_m": binned(
                e, depth, [-1, 0.005, 0.1, 0.2, 0.3, 0.4, 0.5, 2], inside & measured & (slope < 10)
            ),
        }
        # Curvature: a smoothing surface is low on convex (lap < 0) and high on
        # concave ground; a slope alone would not care about the sign.
        lap = laplacian(ts, 4, dgt[1])
        cb = [-1e9, -5, -1, 1, 5, 1e9]
        rec["inside_measured_by_laplacian_2cm_per_m"] = binned(e, lap, cb, inside & measured)
        rec["outside_measured_by_laplacian_2cm_per_m"] = binned(e, lap, cb, outside & measured)
        cross = []
        for lo, hi in ((0, 10), (10, 30), (30, 60), (60, 90.01)):
            for name, cm in (("convex_lap_lt_-1", lap < -1), ("flat_abs_lap_le_1", np.abs(lap) <= 1),
                             ("concave_lap_gt_1", lap > 1)):
                st = stats_mm(e[inside & measured & (slope >= lo) & (slope < hi) & cm])
                st.update({"slope_deg": f"{lo}-{hi}", "curvature": name})
                cross.append(st)
        rec["inside_measured_by_slope_and_curvature"] = cross
        # e ~ a + g (G_s * truth - truth): gain g of a Gaussian smoothing of s
        core = np.zeros(e.shape, bool)
        core[40:-40, 40:-40] = True
        gfit = []
        for s_mm in (5, 10, 15, 20):
            dsm = gauss_smooth(ts, s_mm / 1000 / dgt[1]) - ts
            for name, m in (("inside", inside), ("outside", outside)):
                mm = m & core & measured & np.isfinite(dsm)
                if mm.sum() < 100:
                    continue
                Am = np.column_stack([np.ones(mm.sum()), dsm[mm]])
                sol = np.linalg.lstsq(Am, e[mm], rcond=None)[0]
                r = e[mm] - Am @ sol
                gfit.append({"sigma_mm": s_mm, "where": name, "gain": round(float(sol[1]), 4),
                             "offset_mm": round(float(sol[0]) * 1000, 4),
                             "residual_std_mm": round(float(r.std()) * 1000, 4),
                             "raw_std_mm": round(float(e[mm].std()) * 1000, 4)})
        rec["gaussian_smoothing_fit"] = gfit
        zs = e / sig
        rec["error_over_sigma"] = {
            "inside": z_stats(zs[inside & measured]),
            "outside": z_stats(zs[outside & measured]),
            "sigma_median_mm_inside": round(float(np.nanmedian(sig[inside & measured]) * 1000), 4)
            if (inside & measured).any() else None,
            "sigma_median_mm_outside": round(float(np.nanmedian(sig[outside & measured]) * 1000), 4)
            if (outside & measured).any() else None,
        }
        sb = []
        for lo, hi in [(0, 0.001), (0.001, 0.002), (0.002, 0.003), (0.003, 0.005), (0.005, 0.01), (0.01, 1)]:
            for name, m in (("inside", inside), ("outside", outside)):
                mm = m & measured & (sig >= lo) & (sig < hi)
                s = stats_mm(e[mm])
                s.update({"sigma_bin_mm": f"{lo*1000:g}-{hi*1000:g}", "where": name})
                if s["n"]:
                    s["nmad_over_median_sigma"] = round(s["nmad_mm"] / (float(np.median(sig[mm])) * 1000), 4)
                sb.append(s)
        rec["by_stated_sigma"] = sb
        rec["plane_and_shift_fit"] = {
            "outside_measured": fit_shift(e, gx_, gy_, X, Y, outside & measured),
            "inside_measured": fit_shift(e, gx_, gy_, X, Y, inside & measured),
            "inside_measured_slope_lt_30": fit_shift(e, gx_, gy_, X, Y, inside & measured & (slope < 30)),
        }
        result["layers"][L] = rec
        if grid is None:
            grid = (list(dgt), dtm.shape, x[0], y[0])
        E[L], D[L], T[L] = e, dtm, ts
        grid_of[L] = list(dgt)
        E[L + "_grid"] = (x[0], y[0], dtm.shape, inside, outside, measured)

    # Consecutive layers: what enters each unit's volume.
    for a, b in zip(layers[:-1], layers[1:]):
        if a not in E or b not in E:
            result["inter_layer"].append({"layers": f"{a}-{b}", "unit": layer_unit.get(a), "computed": False,
                                          "reason": "a DTM is missing"})
            continue
        ga, gb = E[a + "_grid"], E[b + "_grid"]
        # Each layer's DTM has its own extent, and may have its own cell size: compare
        # at the cells of a's DTM, taking b's nearest cell (exact when the two share
        # a lattice; within half of b's cell otherwise).
        cell_a = abs(grid_of[a][1])
        cell_b = abs(grid_of[b][1])
        (ra, ca), (rb, cb) = ga[2], gb[2]
        xa = ga[0] + np.arange(ca) * cell_a  # centres (ga[0], ga[1]: first centre)
        ya = ga[1] - np.arange(ra) * cell_a
        cols_b = np.rint((xa - gb[0]) / cell_b).astype(int)
        rows_b = np.rint((gb[1] - ya) / cell_b).astype(int)
        okc, okr = (cols_b >= 0) & (cols_b < cb), (rows_b >= 0) & (rows_b < rb)
        if not okc.any() or not okr.any():
            result["inter_layer"].append({"layers": f"{a}-{b}", "computed": False, "reason": "DTMs do not overlap"})
            continue
        ic, ir = np.nonzero(okc)[0], np.nonzero(okr)[0]
        wa = np.ix_(ir, ic)
        wb = np.ix_(rows_b[ir], cols_b[ic])
        inside, outside = ga[3][wa], ga[4][wa]
        both = ga[5][wa] & gb[5][wb]
        tb, _ = bilinear(truth[b][0], truth[b][1], xa[ic], ya[ir])  # truth of b at a's cells
        tth = T[a][wa] - tb
        dug = inside & (tth > args.min_thickness)
        de = E[a][wa] - E[b][wb]  # thickness error
        area = cell_a * cell_a
        u = layer_unit.get(a)
        ok = dug & np.isfinite(de)
        rec = {
            "layers": f"{a}-{b}",
            "unit": u,
            "computed": True,
            "dug_cells": int(dug.sum()),
            "dug_cells_compared": int(ok.sum()),
            "thickness_error_dug": stats_mm(de[ok]),
            "thickness_error_dug_both_measured": stats_mm(de[dug & both]),
            "thickness_error_outside_both_measured": stats_mm(de[outside & both]),
            "truth_volume_dug_cells_m3": float(np.nansum(tth[ok]) * area),
            "volume_error_dug_m3": float(np.nansum(de[ok]) * area),
        }
        rec["volume_error_dug_pct"] = 100 * rec["volume_error_dug_m3"] / rec["truth_volume_dug_cells_m3"]
        if u in units:
            rec["units_csv_volume_m3"] = units[u]["volume_m3"]
            rec["volume_error_pct_of_units_csv"] = 100 * rec["volume_error_dug_m3"] / units[u]["volume_m3"]
        # the same with the stable ground's offset removed (what strata's
        # significance test does with o)
        off = np.median(de[outside & both]) if (outside & both).any() else 0.0
        rec["volume_error_dug_minus_stable_offset_m3"] = float(np.nansum(de[ok] - off) * area)
        result["inter_layer"].append(rec)

    # MODEL, not a measurement: what a height-field Gaussian smoothing of the
    # truth surfaces (sigma 5/10/15 mm, the scale the L1 fit above suggests)
    # alone would do to each unit's volume: with the outline (dug cells inside
    # it, truth thickness > min) and without (cells dug or changed by > 1 mm).
    model = []
    if all(L in truth for L in layers):
        sm_cache = {}
        for s_mm in (5, 10, 15):
            for L in layers:
                sm_cache[L] = gauss_smooth(truth[L][0], s_mm / 1000 / cell_t) - truth[L][0]
            for a, b in zip(layers[:-1], layers[1:]):
                u = layer_unit.get(a)
                if u not in units:
                    continue
                th = truth[a][0] - truth[b][0]
                de = sm_cache[a] - sm_cache[b]
                area = cell_t * cell_t
                v = units[u]["volume_m3"]
                e_out = float(de[t_in & (th > args.min_thickness)].sum() * area)
                e_no = float(de[(th > args.min_thickness) | (np.abs(de) > 0.001)].sum() * area)
                model.append({"sigma_mm": s_mm, "unit": u, "with_outline_m3": e_out,
                              "with_outline_pct": 100 * e_out / v, "without_outline_m3": e_no,
                              "without_outline_pct": 100 * e_no / v})
    result["model_height_field_smoothing_not_measured"] = model
    result["float32_ulp_at_1450m_mm"] = float(np.spacing(np.float32(1450.0))) * 1000
    # provenance: when the project's DTMs were made
    gp = os.path.join(args.project, "project.gpkg")
    if os.path.exists(gp):
        try:
            import sqlite3
            c = sqlite3.connect(f"file:{gp}?mode=ro", uri=True)
            result["project_products"] = [
                {"layer": r[0], "kind": r[1], "created_at": r[2], "sha256": r[3]}
                for r in c.execute("select l.name, p.kind, p.created_at, p.sha256 from products p "
                                   "join layers l on l.id = p.layer_id where p.kind in ('dtm','dtm_sigma','surface')")
            ]
            c.close()
        except Exception as ex:  # noqa: BLE001
            result["project_products"] = f"unreadable: {ex}"

    out = args.out
    if not out:
        d = datetime.datetime.now(datetime.timezone.utc).strftime("%Y%m%d")
        out = os.path.join(HERE, "results", f"dtm-bias-{d}.json")
    with open(out, "w") as f:
        json.dump(result, f, indent=1)
        f.write("\n")
    print(out)


if __name__ == "__main__":
    main()
