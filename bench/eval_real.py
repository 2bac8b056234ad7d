#!/usr/bin/python3
"""Scores strata and COLMAP on real photo sets with truth (bench/real.sh).

Usage: eval_real.py --work DIR --data DIR --sets herz entry copr [--previous JSON]
                    [--load-before L] --out JSON

For every set and tool (files left by bench/real.sh under WORK/SET/{strata,colmap}):
  registered / total photos; reprojection RMSE over every observation (px; strata's
  own figure, COLMAP's recomputed from its text model); camera centres after the
  least-squares 7-parameter similarity onto the true centres (Umeyama 1991): RMSE and
  max (m, truth frame) and the rotation error of every camera in that frame (deg,
  median / max); the focal found against the true one; wall / CPU time and peak RSS
  (/usr/bin/time -v).
copr (no true cameras, 10 surveyed targets clicked by hand, heights unknown):
  strata's own control RMSE (plan), and for both tools the markers triangulated from
  the clicks with that tool's cameras and fitted to the survey by a plan similarity
  (markers.py), with every observation's agreement with the other rays in pixels.
Every figure is compared with the previous run as a ratio (now / before).

Needs the Debian python3-numpy (run it with /usr/bin/python3).
"""
import argparse
import json
import math
import os
import re
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import markers  # noqa: E402  (bench/markers.py: cameras, triangulation, plan fits)

QUIET_LOAD = 0.5  # 1-minute load average above which the machine was not free for timing
STRECHA = {"herz": "strecha/Herz-Jesus-P8", "entry": "strecha/entry-P10"}
# copr: Canon "DIGITAL REBEL XSi", 30 mm lens setting, 22.2 mm wide sensor, photos
# halved to 2136 px: the nominal focal from EXIF (no calibration is published).
COPR_NOMINAL_FOCAL_PX = 30.0 / 22.2 * 2136


# ---- inputs

def read_json(path):
    with open(path) as f:
        return json.load(f)


def read_time_v(path):
    """Wall and CPU seconds and peak RSS (MB) from a `/usr/bin/time -v` report."""
    if not os.path.exists(path):
        return None
    text = open(path).read()
    out = {}
    m = re.search(r"Elapsed \(wall clock\) time.*: (?:(\d+):)?(\d+):([\d.]+)", text)
    if m:
        out["wall_s"] = int(m.group(1) or 0) * 3600 + int(m.group(2)) * 60 + float(m.group(3))
    user = re.search(r"User time \(seconds\): ([\d.]+)", text)
    system = re.search(r"System time \(seconds\): ([\d.]+)", text)
    if user and system:
        out["cpu_s"] = float(user.group(1)) + float(system.group(1))
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", text)
    if rss:
        out["peak_rss_mb"] = round(int(rss.group(1)) / 1024.0, 1)
    status = re.search(r"Exit status: (\d+)", text)
    if status:
        out["exit_status"] = int(status.group(1))
    return out


def combine_times(parts):
    """Sum of the times of consecutive commands, the largest of their peaks."""
    parts = [p for p in parts if p]
    if not parts:
        return None
    return {"wall_s": round(sum(p.get("wall_s", 0) for p in parts), 2),
            "cpu_s": round(sum(p.get("cpu_s", 0) for p in parts), 2),
            "peak_rss_mb": max(p.get("peak_rss_mb", 0) for p in parts)}


def read_strecha_truth(folder):
    """{image: (K, R world-to-camera, C)} from the benchmark's .camera files."""
    out = {}
    cams = os.path.join(folder, "gt_dense_cameras")
    for name in sorted(os.listdir(cams)):
        rows = [list(map(float, l.split())) for l in open(os.path.join(cams, name)) if l.strip()]
        k = np.array(rows[0:3])
        r_c2w = np.array(rows[4:7])
        c = np.array(rows[7])
        out[name[:-len(".camera")]] = (k, r_c2w.T, c)
    return out


# ---- accuracy against the truth

def umeyama(src, dst):
    """s, R, t minimising sum |dst - (s R src + t)|^2 (Umeyama 1991, with the reflection fix)."""
    ms, md = src.mean(0), dst.mean(0)
    a, b = src - ms, dst - md
    u, sv, vt = np.linalg.svd(b.T @ a / len(src))
    d = np.eye(src.shape[1])
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        d[-1, -1] = -1
    rot = u @ d @ vt
    scale = np.trace(np.diag(sv) @ d) / (a ** 2).sum(1).mean()
    return scale, rot, md - scale * rot @ ms


def rotation_angle_deg(r):
    return math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(r) - 1) / 2))))


def score_against_truth(cams, truth):
    """Centre and rotation errors of {image: Camera} after the similarity onto the true centres."""
    names = sorted(k for k in cams if k in truth)
    if len(names) < 3:
        return None
    est = np.array([cams[k].centre for k in names])
    ref = np.array([truth[k][2] for k in names])
    s, rot, t = umeyama(est, ref)
    err = np.linalg.norm((s * (rot @ est.T)).T + t - ref, axis=1)
    # World-to-camera in the truth frame: R_est * rot^T; its error against the true one.
    ang = np.array([rotation_angle_deg(cams[k].R @ rot.T @ truth[k][1].T) for k in names])
    spread = float(np.sqrt(((ref - ref.mean(0)) ** 2).sum(1).mean()))
    return {"cameras": len(names),
            "centre_rmse_m": float(np.sqrt((err ** 2).mean())), "centre_max_m": float(err.max()),
            "centre_rmse_rel": float(np.sqrt((err ** 2).mean())) / spread,
            "rotation_median_deg": float(np.median(ang)), "rotation_max_deg": float(ang.max()),
            "camera_spread_m": spread}


def focal_figures(found, true):
    if found is None:
        return {}
    out = {"focal_px": found}
    if true:
        out["focal_true_px"] = true
        out["focal_error_pct"] = 100.0 * (found - true) / true
    return out


# ---- one tool on one set

def strata_side(folder, total, truth, true_focal):
    sparse_path = os.path.join(folder, "sparse.json")
    q = {}
    if os.path.exists(sparse_path) and os.path.getsize(sparse_path) > 0:
        try:
            q = read_json(sparse_path)
        except json.JSONDecodeError:
            q = {}
    cams = markers.read_strata_cameras(os.path.join(folder, "cameras.csv"))
    out = {"registered": len(cams), "total": total,
           "reprojection_rmse_px": q.get("reprojection_rmse_px"),
           "time": read_time_v(sparse_path + ".time")}
    if not q:
        out["failed"] = last_error_line(os.path.join(folder, "log.txt"))
    fx = np.median([c.fx for c in cams.values()]) if cams else None
    out.update(focal_figures(float(fx) if fx is not None else None, true_focal))
    if truth:
        out["truth"] = score_against_truth(cams, truth)
    if q.get("georeferenced"):
        c = q.get("control_rmse", {})
        out["control_rmse_plan_m"] = math.hypot(c.get("e_m", 0), c.get("n_m", 0)) if c.get("markers") else None
        out["control_markers"] = c.get("markers")
        loo = q.get("leave_one_out_rmse", {})
        out["leave_one_out_rmse_plan_m"] = (math.hypot(loo.get("e_m", 0), loo.get("n_m", 0))
                                            if loo.get("markers") else None)
    return out, cams, q


def last_error_line(log):
    if not os.path.exists(log):
        return None
    lines = [l.strip() for l in open(log) if l.strip()]
    return lines[-1] if lines else None


def colmap_side(folder, total, truth, true_focal):
    if not os.path.isdir(folder):
        return None, {}, None
    model = os.path.join(folder, "txt")
    times = combine_times([read_time_v(os.path.join(folder, n + ".log.time")) for n in ("extract", "match", "mapper")])
    out = {"time": times, "total": total, "camera_model": None}
    if not os.path.exists(os.path.join(model, "images.txt")):
        out["registered"] = 0
        return out, {}, None
    cams, intrinsics = markers.read_colmap_cameras(model)
    points = markers.read_colmap_points(model)
    out["registered"] = len(cams)
    out["models"] = int(open(os.path.join(folder, "models.txt")).read().strip() or 0)
    out["camera_model"] = sorted({c.model for c in intrinsics.values()})
    out["points"] = len(points)
    out["reprojection_rmse_px"] = markers.colmap_reprojection_rmse(model, cams, points)
    out.update(focal_figures(float(np.median([c.fx for c in cams.values()])), true_focal))
    if truth:
        out["truth"] = score_against_truth(cams, truth)
    return out, cams, points


# ---- comparison with the previous run

RATIO_KEYS = ["registered", "reprojection_rmse_px", "focal_error_pct", "control_rmse_plan_m",
              "truth.centre_rmse_m", "truth.centre_max_m", "truth.rotation_median_deg",
              "truth.rotation_max_deg", "time.wall_s", "time.cpu_s", "time.peak_rss_mb",
              "independent.plan_rmse_m"]


def lookup(d, dotted):
    for k in dotted.split("."):
        if not isinstance(d, dict) or d.get(k) is None:
            return None
        d = d[k]
    return d


def ratios(now, before):
    out = {}
    for key in RATIO_KEYS:
        a, b = lookup(now, key), lookup(before, key)
        if isinstance(a, (int, float)) and isinstance(b, (int, float)) and b != 0:
            out[key] = round(a / b, 3)
    return out


# ---- printing

def fmt(v, digits=3):
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}g}" if abs(v) < 1e-2 and v != 0 else f"{v:.{digits}f}"
    return str(v)


def print_table(result):
    rows = [("registered / total", lambda t: f"{t.get('registered')}/{t.get('total')}" if t else "-"),
            ("reprojection RMSE px", lambda t: fmt(t.get("reprojection_rmse_px"))),
            ("focal px (true)", lambda t: f"{fmt(t.get('focal_px'), 1)} ({fmt(t.get('focal_true_px'), 1)})"),
            ("focal error %", lambda t: fmt(t.get("focal_error_pct"), 2)),
            ("centre RMSE / max m", lambda t: f"{fmt(lookup(t, 'truth.centre_rmse_m'), 4)} / "
                                              f"{fmt(lookup(t, 'truth.centre_max_m'), 4)}"),
            ("rotation med / max deg", lambda t: f"{fmt(lookup(t, 'truth.rotation_median_deg'), 3)} / "
                                                 f"{fmt(lookup(t, 'truth.rotation_max_deg'), 3)}"),
            ("control RMSE plan m", lambda t: fmt(t.get("control_rmse_plan_m"))),
            ("markers: plan fit RMSE m", lambda t: fmt(lookup(t, "independent.plan_rmse_m"))),
            ("wall / CPU s", lambda t: f"{fmt(lookup(t, 'time.wall_s'), 1)} / {fmt(lookup(t, 'time.cpu_s'), 1)}"),
            ("peak RSS MB", lambda t: fmt(lookup(t, "time.peak_rss_mb"), 1))]
    for name, s in result["sets"].items():
        print(f"\n{name}: {s['photos']} photos")
        print(f"  {'figure':<26} {'strata':>22} {'COLMAP':>22}  ratio to previous (strata, COLMAP)")
        for label, get in rows:
            st, co = s.get("strata") or {}, s.get("colmap") or {}
            print(f"  {label:<26} {get(st):>22} {get(co) if co else '-':>22}")
        for tool in ("strata", "colmap"):
            r = (s.get("ratio_to_previous") or {}).get(tool)
            if r:
                print(f"  previous run, {tool}: " + ", ".join(f"{k} {v}" for k, v in r.items()))
        if "markers" in s:
            markers.print_marker_table(s["markers"])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--work", required=True)
    ap.add_argument("--data", required=True)
    ap.add_argument("--sets", nargs="+", required=True)
    ap.add_argument("--previous")
    ap.add_argument("--load-before")
    ap.add_argument("--out", required=True)
    ap.add_argument("--latest", help="updated with this run's sets (the others kept)")
    a = ap.parse_args()

    result = {"sets": {}, "load_average_before": float(a.load_before) if a.load_before else None}
    if result["load_average_before"] is not None and result["load_average_before"] > QUIET_LOAD:
        result["timing_warning"] = (f"load average {result['load_average_before']:.2f} before the run: "
                                    "other work shared the cores, the times are not comparable")
        print("bench: warning: " + result["timing_warning"], file=sys.stderr)
    previous = read_json(a.previous) if a.previous and os.path.exists(a.previous) else {}
    for name in a.sets:
        if name in STRECHA:
            folder = os.path.join(a.data, STRECHA[name])
            truth = read_strecha_truth(folder)
            true_focal = float(np.mean([0.5 * (k[0, 0] + k[1, 1]) for k, _, _ in truth.values()]))
            photos = len(truth)
        else:
            folder = os.path.join(a.data, "copr")
            truth, true_focal = None, None
            photos = len([f for f in os.listdir(os.path.join(folder, "images")) if f.endswith(".jpg")])
        st, st_cams, st_quality = strata_side(os.path.join(a.work, name, "strata"), photos, truth, true_focal)
        co, co_cams, co_points = colmap_side(os.path.join(a.work, name, "colmap"), photos, truth, true_focal)
        s = {"photos": photos, "strata": st, "colmap": co}
        if name == "copr":
            st["focal_nominal_exif_px"] = COPR_NOMINAL_FOCAL_PX
            if co:
                co["focal_nominal_exif_px"] = COPR_NOMINAL_FOCAL_PX
            s["markers"] = markers.copr_analysis(os.path.join(folder, "gcp_list.txt"), st_cams, st_quality,
                                                 co_cams, co_points)
            for tool, side in (("strata", st), ("colmap", co)):
                fit = (s["markers"].get(tool) or {}).get("fit")
                if side is not None and fit:
                    side["independent"] = {"plan_rmse_m": fit["plan_rmse_m"],
                                           "leave_one_out_plan_rmse_m": fit["leave_one_out_plan_rmse_m"],
                                           "markers": len(fit["markers"])}
        before = (previous.get("sets") or {}).get(name)
        if before:
            s["ratio_to_previous"] = {tool: ratios(s.get(tool) or {}, before.get(tool) or {})
                                      for tool in ("strata", "colmap")}
        result["sets"][name] = s
    with open(a.out, "w") as f:
        json.dump(result, f, indent=2)
    if a.latest:
        # Only the sets: a partial run (--set copr) keeps the other sets' last figures.
        merged = {"sets": dict(previous.get("sets") or {}, **result["sets"])}
        with open(a.latest, "w") as f:
            json.dump(merged, f, indent=2)
    print_table(result)


if __name__ == "__main__":
    sys.exit(main())
