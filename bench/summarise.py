#!/usr/bin/python3
"""Summarises one benchmark run: stage times, peak memory, camera accuracy against
the synthetic truth, ratios to the target and to the previous run, and the COLMAP
comparison when COLMAP ran.

Camera accuracy is given two ways:
  - georeferenced: strata's camera centres in the site CRS against the truth, with
    nothing fitted (what the user gets);
  - shape: after the best similarity (7 parameters) between the estimated and the true
    centres. COLMAP has no markers, so its model is only comparable this way; strata's
    shape figure is computed the same way for a like-for-like comparison.
"""
import argparse, csv, json, math, os, sys

import numpy as np

# The field target: a layer's verdict within about the minute it took to shoot, on
# the 2 cores of a field laptop.
TARGET_LAYER_SECONDS = 60.0
QUIET_LOAD = 0.5  # 1-minute load average above which the machine was not free for timing


def read_json(path):
    with open(path) as f:
        return json.load(f)


def strata_centres(path):
    out = {}
    with open(path) as f:
        for row in csv.DictReader(f):
            out[row["image"]] = np.array([float(row["X"]), float(row["Y"]), float(row["Z"])])
    return out


def colmap_centres(images_txt):
    """Camera centres C = -R^T t from a COLMAP text model (images.txt)."""
    out = {}
    with open(images_txt) as f:
        lines = [l for l in f if not l.startswith("#")]
    for header in lines[0::2]:
        p = header.split()
        if len(p) < 10:
            continue
        qw, qx, qy, qz, tx, ty, tz = map(float, p[1:8])
        r = np.array([
            [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy)],
            [2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx)],
            [2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)]])
        out[p[9]] = -r.T @ np.array([tx, ty, tz])
    return out


def similarity_residuals(est, truth):
    """Residuals (m) of est mapped onto truth by the least-squares similarity (Umeyama 1991)."""
    names = sorted(k for k in est if k in truth)
    if len(names) < 3:
        return []
    a = np.array([est[k] for k in names])
    b = np.array([truth[k] for k in names])
    ma, mb = a.mean(0), b.mean(0)
    a0, b0 = a - ma, b - mb
    u, s, vt = np.linalg.svd(b0.T @ a0 / len(names))
    d = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        d[2, 2] = -1
    rot = u @ d @ vt
    scale = np.trace(np.diag(s) @ d) / (a0 ** 2).sum(1).mean()
    mapped = (scale * (rot @ a0.T)).T + mb
    return sorted(np.linalg.norm(mapped - b, axis=1).tolist())


def stats(errors):
    if not errors:
        return None
    return {"n": len(errors), "median_m": errors[len(errors) // 2], "max_m": errors[-1],
            "rmse_m": math.sqrt(sum(e * e for e in errors) / len(errors))}


def main():
    ap = argparse.ArgumentParser()
    for name in ["size", "layer", "photos", "sparse", "sparse-seconds", "dense", "dense-seconds",
                 "products-seconds", "memdir", "cameras", "truth", "colmap", "surface", "points", "previous", "load-before",
                 "align-args", "out"]:
        ap.add_argument("--" + name)
    a = ap.parse_args()
    sparse = read_json(a.sparse)
    dense = read_json(a.dense).get("dense", {}) if a.dense and os.path.exists(a.dense) else {}
    est, truth = strata_centres(a.cameras), strata_centres(a.truth)
    direct = sorted(float(np.linalg.norm(est[k] - truth[k])) for k in est if k in truth)
    seconds = {k: float(v) for k, v in [("sparse", a.sparse_seconds), ("dense", a.dense_seconds),
                                        ("products", a.products_seconds)] if v}
    result = {
        "size": a.size, "layer": a.layer, "photos": int(a.photos),
        "sparse_seconds": seconds.get("sparse"), "dense_seconds": seconds.get("dense"),
        "products_seconds": seconds.get("products"),
        "layer_seconds": sum(seconds.values()),
        "target_layer_seconds": TARGET_LAYER_SECONDS,
        "registered": sparse.get("images_registered"),
        "reprojection_rmse_px": sparse.get("reprojection_rmse_px"),
        "control_rmse_xyz_m": sparse.get("control_rmse", {}).get("xyz_m"),
        "check_rmse_xyz_m": sparse.get("check_rmse", {}).get("xyz_m"),
        "camera_centres_georeferenced": stats(direct),
        "camera_centres_shape": stats(similarity_residuals(est, truth)),
        "pairs": sparse.get("pairs"),
        "sparse_timings": sparse.get("timings"), "sparse_peak_memory_mb": sparse.get("peak_memory_mb"),
        "dense_steps": dense.get("steps"), "dense_completeness": dense.get("completeness"),
        "surface": read_json(a.surface) if a.surface and os.path.exists(a.surface) else None,
        "points": read_json(a.points) if a.points and os.path.exists(a.points) else None,
        "colmap": json.loads(a.colmap) if a.colmap and a.colmap != "null" else None,
        "load_average_before": float(a.load_before) if a.load_before else None,
        "align_args": a.align_args or "",
    }
    if result["load_average_before"] is not None and result["load_average_before"] > QUIET_LOAD:
        result["timing_warning"] = (f"load average {result['load_average_before']:.2f} before the run: "
                                    "other work shared the cores, the times are not comparable")
        print("bench: warning: " + result["timing_warning"], file=sys.stderr)
    if a.memdir:
        for stage in ["sparse", "dense", "products"]:
            path = os.path.join(a.memdir, stage + ".mem")
            if os.path.exists(path):
                with open(path) as f:
                    fields = f.read().split()
                result[stage + "_peak_rss_mb"] = round(int(fields[0]) / 1024.0, 1)
                if len(fields) >= 3:  # user and system CPU seconds
                    result[stage + "_cpu_seconds"] = round(float(fields[1]) + float(fields[2]), 2)
        cpu = [result.get(s + "_cpu_seconds") for s in ["sparse", "dense", "products"]]
        if all(c is not None for c in cpu):
            result["layer_cpu_seconds"] = round(sum(cpu), 2)
    result["ratio_to_target"] = result["layer_seconds"] / TARGET_LAYER_SECONDS
    c = result["colmap"]
    if c:
        images = os.path.join(c.get("model", ""), "images.txt")
        if os.path.exists(images):
            cc = colmap_centres(images)
            c["registered"] = len(cc)
            c["camera_centres_shape"] = stats(similarity_residuals(cc, truth))
        c.pop("model", None)
        if c.get("seconds"):
            result["ratio_sparse_to_colmap"] = result["sparse_seconds"] / c["seconds"]
        if c.get("cpu_seconds") and result.get("sparse_cpu_seconds"):
            result["ratio_sparse_cpu_to_colmap"] = result["sparse_cpu_seconds"] / c["cpu_seconds"]
    if a.previous and os.path.exists(a.previous):
        prev = read_json(a.previous)
        result["ratio_to_previous"] = {k: result[k] / prev[k] for k in
                                       ["sparse_seconds", "dense_seconds", "products_seconds", "layer_seconds",
                                        "layer_cpu_seconds"]
                                       if prev.get(k) and result.get(k)}
    with open(a.out, "w") as f:
        json.dump(result, f, indent=2)
    keys = ["timing_warning", "photos", "registered", "sparse_seconds", "dense_seconds", "products_seconds", "layer_seconds",
            "ratio_to_target", "reprojection_rmse_px", "check_rmse_xyz_m", "camera_centres_georeferenced",
            "camera_centres_shape", "sparse_peak_rss_mb", "dense_peak_rss_mb", "products_peak_rss_mb",
            "sparse_cpu_seconds", "dense_cpu_seconds", "products_cpu_seconds", "layer_cpu_seconds",
            "dense_completeness", "surface", "points", "colmap", "ratio_sparse_to_colmap", "ratio_sparse_cpu_to_colmap",
            "ratio_to_previous"]
    print(json.dumps({k: result.get(k) for k in keys if result.get(k) is not None}, indent=2))


if __name__ == "__main__":
    sys.exit(main())
