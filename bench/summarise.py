#!/usr/bin/env python3
"""Summarises one benchmark run: stage times, peak memory, camera accuracy against
the synthetic truth (after nothing but the georeference: both are in the site CRS),
ratios to the target and to the previous run. Standard library only."""
import argparse, csv, json, math, os, sys

TARGET_LAYER_SECONDS = 180.0  # issue 5: whole per-layer pipeline under 3 minutes on 2 cores


def read_json(path):
    with open(path) as f:
        return json.load(f)


def camera_centres(path):
    out = {}
    with open(path) as f:
        for row in csv.DictReader(f):
            out[row["image"]] = (float(row["X"]), float(row["Y"]), float(row["Z"]))
    return out


def main():
    ap = argparse.ArgumentParser()
    for name in ["size", "layer", "photos", "sparse", "sparse-seconds", "dense", "dense-seconds",
                 "cameras", "truth", "colmap", "previous", "out"]:
        ap.add_argument("--" + name)
    a = ap.parse_args()
    sparse = read_json(a.sparse)
    dense = read_json(a.dense).get("dense", {})
    est, truth = camera_centres(a.cameras), camera_centres(a.truth)
    errors = [math.dist(est[k], truth[k]) for k in est if k in truth]
    errors.sort()
    result = {
        "size": a.size, "layer": a.layer, "photos": int(a.photos),
        "sparse_seconds": float(a.sparse_seconds), "dense_seconds": float(a.dense_seconds),
        "layer_seconds": float(a.sparse_seconds) + float(a.dense_seconds),
        "target_layer_seconds": TARGET_LAYER_SECONDS,
        "registered": sparse.get("images_registered"), "reprojection_rmse_px": sparse.get("reprojection_rmse_px"),
        "control_rmse_xyz_m": sparse.get("control_rmse", {}).get("xyz_m"),
        "check_rmse_xyz_m": sparse.get("check_rmse", {}).get("xyz_m"),
        "camera_centre_error_median_m": errors[len(errors) // 2] if errors else None,
        "camera_centre_error_max_m": errors[-1] if errors else None,
        "sparse_timings": sparse.get("timings"), "sparse_peak_memory_mb": sparse.get("peak_memory_mb"),
        "dense_steps": dense.get("steps"), "dense_completeness": dense.get("completeness"),
        "colmap": json.loads(a.colmap) if a.colmap and a.colmap != "null" else None,
    }
    result["ratio_to_target"] = result["layer_seconds"] / TARGET_LAYER_SECONDS
    if result["colmap"]:
        result["ratio_sparse_to_colmap"] = result["sparse_seconds"] / result["colmap"]["seconds"]
    if a.previous and os.path.exists(a.previous):
        prev = read_json(a.previous)
        result["ratio_to_previous"] = {k: result[k] / prev[k] for k in ["sparse_seconds", "dense_seconds", "layer_seconds"]
                                       if prev.get(k)}
    with open(a.out, "w") as f:
        json.dump(result, f, indent=2)
    print(json.dumps({k: result[k] for k in ["layer_seconds", "ratio_to_target", "registered",
                                               "check_rmse_xyz_m", "camera_centre_error_median_m"]}, indent=2))


if __name__ == "__main__":
    sys.exit(main())
