"""Cameras of strata and COLMAP, and copr's hand-clicked markers triangulated in them
independently of strata's georeference. Used by eval_real.py.

Pixel convention here is strata's (docs: src/geometry/camera.hpp): (0, 0) is the centre
of the top-left pixel. COLMAP puts the corner there, so its principal points and its
keypoints are moved by -0.5 px on reading. The ODM gcp_list clicks are taken in strata's
convention, as strata's importer takes them.

Method for copr (heights unknown, all 0.0 in the survey):
  1. every marker seen in >= 2 registered photos is triangulated from its clicks with
     the tool's cameras: the least-squares midpoint of the rays, then Gauss-Newton on
     the pixel reprojection error (numerical Jacobian, 3 unknowns);
  2. each click's agreement with the other rays: the distance (px) from the click to the
     projection of the point triangulated from that marker's *other* clicks (>= 3 clicks),
     and the residual at the point from all clicks;
  3. one click per marker whose distance to the other rays exceeds CLICK_OUTLIER_PX is
     named and left out (a click on another target is hundreds of pixels away);
  4. the model is levelled (COLMAP: on the robust plane of its whole sparse cloud, the
     beach; strata: its own site frame, z up) and fitted to the surveyed E, N by a
     4-parameter plan similarity (2D Umeyama). Why not 3D with the heights free: the
     markers lie on a nearly flat beach, and for coplanar points the plan projection of a
     rotated, scaled plane is any 2D affine map, so the tilt would be traded for plan fit
     (6 effective parameters for 2n equations). Levelling on the ground instead costs
     little: a tilt error t changes plan distances by (1 - cos t), 0.4 % at 5 deg, 8 cm
     over 20 m, against metre-level misfits. The 2D affine fit is reported too: it is
     the best that any tilt, scale or shear could do, so its residual is a bound that
     no levelling can beat;
  5. leave-one-out: each marker predicted by the fit on the others.
"""
import csv
import math
import os

import numpy as np

CLICK_OUTLIER_PX = 10.0  # a click this far from the other rays is on something else
GN_ITERATIONS = 20        # Gauss-Newton steps of a marker's triangulation (converges in < 5)
UNDISTORT_ITERATIONS = 50  # fixed-point steps of the inverse lens model (mild distortion)
COLMAP_PIXEL_OFFSET = 0.5  # COLMAP pixel (corner origin) = strata pixel (centre origin) + 0.5


class Camera:
    """A pinhole camera with the radial-tangential lens model (strata 'radial', COLMAP
    SIMPLE_RADIAL / RADIAL / OPENCV), world-to-camera R, t; pixels in strata's convention."""

    def __init__(self, model, fx, fy, cx, cy, k1, k2, p1, p2, rot, centre):
        self.model = model
        self.fx, self.fy, self.cx, self.cy = fx, fy, cx, cy
        self.k1, self.k2, self.p1, self.p2 = k1, k2, p1, p2
        self.R = np.asarray(rot, dtype=float)
        self.centre = np.asarray(centre, dtype=float)

    def distort(self, x, y):
        r2 = x * x + y * y
        radial = 1 + self.k1 * r2 + self.k2 * r2 * r2
        xd = x * radial + 2 * self.p1 * x * y + self.p2 * (r2 + 2 * x * x)
        yd = y * radial + self.p1 * (r2 + 2 * y * y) + 2 * self.p2 * x * y
        return xd, yd

    def project(self, X):
        """Pixels of world points X (n x 3); NaN behind the camera."""
        xc = (np.atleast_2d(X) - self.centre) @ self.R.T
        z = np.where(xc[:, 2] > 0, xc[:, 2], np.nan)
        xd, yd = self.distort(xc[:, 0] / z, xc[:, 1] / z)
        return np.column_stack([self.fx * xd + self.cx, self.fy * yd + self.cy])

    def ray(self, pixel):
        """Unit world direction of the ray through a pixel."""
        xd, yd = (pixel[0] - self.cx) / self.fx, (pixel[1] - self.cy) / self.fy
        x, y = xd, yd
        for _ in range(UNDISTORT_ITERATIONS):
            dx, dy = self.distort(x, y)
            x, y = x + (xd - dx), y + (yd - dy)
        d = self.R.T @ np.array([x, y, 1.0])
        return d / np.linalg.norm(d)


# ---- readers

def read_strata_cameras(path):
    """{image: Camera} from `strata export cameras --format csv` (radial k1, k2 only)."""
    out = {}
    if not os.path.exists(path) or os.path.getsize(path) == 0:
        return out
    with open(path) as f:
        for row in csv.DictReader(f):
            v = {k: float(x) for k, x in row.items() if k != "image"}
            rot = [[v[f"r{i}{j}"] for j in (1, 2, 3)] for i in (1, 2, 3)]
            out[row["image"]] = Camera("strata radial", v["fx"], v["fy"], v["ppx"], v["ppy"], v["k1"], v["k2"],
                                       0.0, 0.0, rot, [v["X"], v["Y"], v["Z"]])
    return out


def quaternion_to_matrix(qw, qx, qy, qz):
    return np.array([
        [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy)],
        [2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx)],
        [2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)]])


def colmap_intrinsics(model, p):
    """(fx, fy, cx, cy, k1, k2, p1, p2) of a COLMAP camera, COLMAP pixel convention."""
    if model == "SIMPLE_PINHOLE":
        return p[0], p[0], p[1], p[2], 0, 0, 0, 0
    if model == "PINHOLE":
        return p[0], p[1], p[2], p[3], 0, 0, 0, 0
    if model == "SIMPLE_RADIAL":
        return p[0], p[0], p[1], p[2], p[3], 0, 0, 0
    if model == "RADIAL":
        return p[0], p[0], p[1], p[2], p[3], p[4], 0, 0
    if model == "OPENCV":
        return tuple(p[:8])
    raise ValueError(f"markers: COLMAP camera model {model} is not supported here")


def data_lines(path):
    with open(path) as f:
        return [l.rstrip("\n") for l in f if not l.startswith("#")]


class ColmapIntrinsics:
    def __init__(self, model, params):
        self.model, self.params = model, params


def read_colmap_cameras(model_dir):
    """({image: Camera}, {camera_id: ColmapIntrinsics}) from a COLMAP text model."""
    intrinsics = {}
    for line in data_lines(os.path.join(model_dir, "cameras.txt")):
        p = line.split()
        if len(p) >= 5:
            intrinsics[int(p[0])] = ColmapIntrinsics(p[1], [float(x) for x in p[4:]])
    cams = {}
    lines = data_lines(os.path.join(model_dir, "images.txt"))
    for header in lines[0::2]:
        p = header.split()
        if len(p) < 10:
            continue
        rot = quaternion_to_matrix(*map(float, p[1:5]))
        t = np.array(list(map(float, p[5:8])))
        c = intrinsics[int(p[8])]
        fx, fy, cx, cy, k1, k2, p1, p2 = colmap_intrinsics(c.model, c.params)
        cams[p[9]] = Camera("COLMAP " + c.model, fx, fy, cx - COLMAP_PIXEL_OFFSET, cy - COLMAP_PIXEL_OFFSET,
                            k1, k2, p1, p2, rot, -rot.T @ t)
    return cams, intrinsics


def read_colmap_points(model_dir):
    """{point3D_id: xyz} from points3D.txt."""
    out = {}
    for line in data_lines(os.path.join(model_dir, "points3D.txt")):
        p = line.split()
        if len(p) >= 4:
            out[int(p[0])] = np.array(list(map(float, p[1:4])))
    return out


def colmap_reprojection_rmse(model_dir, cams, points):
    """RMS over every observation of a 3D point (px), recomputed from the text model."""
    lines = data_lines(os.path.join(model_dir, "images.txt"))
    sq, n = 0.0, 0
    for header, obs in zip(lines[0::2], lines[1::2]):
        cam = cams.get(header.split()[9])
        v = obs.split()
        if cam is None or not v:
            continue
        a = np.array(v, dtype=float).reshape(-1, 3)
        a = a[a[:, 2] >= 0]
        if not len(a):
            continue
        xyz = np.array([points[int(i)] for i in a[:, 2]])
        r = cam.project(xyz) - (a[:, :2] - COLMAP_PIXEL_OFFSET)
        r = r[np.isfinite(r).all(1)]
        sq += float((r ** 2).sum())
        n += len(r)
    return math.sqrt(sq / n) if n else None


def read_gcp_list(path):
    """(survey {marker: (E, N, Z)}, clicks {marker: [(image, (x, y))]}) from an ODM gcp_list."""
    survey, clicks = {}, {}
    with open(path) as f:
        next(f)  # the CRS line
        for line in f:
            p = line.split()
            if len(p) < 7:
                continue
            name = p[6]
            survey[name] = tuple(map(float, p[0:3]))
            clicks.setdefault(name, []).append((p[5], (float(p[3]), float(p[4]))))
    return survey, clicks


# ---- triangulation

def triangulate(obs):
    """Point from [(Camera, pixel)] by the rays' midpoint, then Gauss-Newton on pixels."""
    a, b = np.zeros((3, 3)), np.zeros(3)
    for cam, px in obs:
        d = cam.ray(px)
        m = np.eye(3) - np.outer(d, d)
        a += m
        b += m @ cam.centre
    X = np.linalg.solve(a, b)
    target = np.array([px for _, px in obs], dtype=float).ravel()

    def residual(x):
        return np.concatenate([cam.project(x)[0] for cam, _ in obs]) - target

    def cost(x):
        r = residual(x)
        return float(r @ r) if np.isfinite(r).all() else math.inf

    scale = max(1e-6, float(np.mean([np.linalg.norm(X - cam.centre) for cam, _ in obs])))
    for _ in range(GN_ITERATIONS):
        r = residual(X)
        if not np.isfinite(r).all():
            break  # behind a camera: the rays do not meet in front of them
        h = 1e-7 * scale
        jac = np.column_stack([(residual(X + h * e) - r) / h for e in np.eye(3)])
        step = np.linalg.lstsq(jac, -r, rcond=None)[0]
        # Backtracking: a step is taken only when it lowers the pixel cost.
        c0, t = float(r @ r), 1.0
        while t > 1e-6 and cost(X + t * step) >= c0:
            t *= 0.5
        if t <= 1e-6:
            break
        X = X + t * step
        if np.linalg.norm(t * step) < 1e-10 * scale:
            break
    return X


def set_distance_to_other_rays(pairs, rows):
    """Each click's distance (px) to the projection of the point from the kept other clicks."""
    for i, row in enumerate(rows):
        others = [pr for j, (pr, r) in enumerate(zip(pairs, rows)) if j != i and not r.get("dropped")]
        if len(others) < 2:
            row["to_other_rays_px"], row["_others_rms_px"] = None, math.inf
            continue
        X = triangulate(others)
        d = float(np.linalg.norm(pairs[i][0].project(X)[0] - pairs[i][1]))
        row["to_other_rays_px"] = d if math.isfinite(d) else None  # None: the others meet behind it
        res = np.concatenate([cam.project(X)[0] - px for cam, px in others])
        row["_others_rms_px"] = float(np.sqrt(np.mean(res ** 2))) if np.isfinite(res).all() else math.inf


def far_click(rows):
    """The click whose removal leaves the best-agreeing others, if it is far from them."""
    i = min(range(len(rows)), key=lambda k: rows[k]["_others_rms_px"])
    d = rows[i]["to_other_rays_px"]
    return i if d is None or d > CLICK_OUTLIER_PX else None


def marker_rays(cams, clicks):
    """Triangulated point and every click's agreement; one far click left out."""
    obs = [(img, px) for img, px in clicks if img in cams]
    rows = [{"image": img, "click": list(px)} for img, px in obs]
    out = {"clicks": len(clicks), "in_registered": len(obs), "observations": rows}
    if len(obs) < 2:
        out["triangulated"] = False
        return out
    pairs = [(cams[img], np.array(px)) for img, px in obs]
    if len(obs) >= 3:
        set_distance_to_other_rays(pairs, rows)
        worst = far_click(rows)
        if worst is not None:
            rows[worst]["dropped"] = True
            set_distance_to_other_rays(pairs, rows)  # again, without the far click
        for row in rows:
            row.pop("_others_rms_px", None)
    kept = [pr for pr, row in zip(pairs, rows) if not row.get("dropped")]
    X = triangulate(kept)
    for (cam, px), row in zip(pairs, rows):
        d = float(np.linalg.norm(cam.project(X)[0] - px))
        row["residual_px"] = d if math.isfinite(d) else None  # None: the point is behind this camera
    if any(row["residual_px"] is None for row in rows if not row.get("dropped")):
        out["triangulated"] = False
        out["reason"] = "the kept rays meet behind a camera"
        return out
    out["triangulated"] = True
    out["point"] = X.tolist()
    kept_res = [row["residual_px"] for row in rows if not row.get("dropped")]
    out["rms_residual_px"] = float(np.sqrt(np.mean(np.square(kept_res))))
    return out


# ---- fits to the survey

def umeyama(src, dst, with_scale=True):
    ms, md = src.mean(0), dst.mean(0)
    a, b = src - ms, dst - md
    u, sv, vt = np.linalg.svd(b.T @ a / len(src))
    d = np.eye(src.shape[1])
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        d[-1, -1] = -1
    rot = u @ d @ vt
    scale = np.trace(np.diag(sv) @ d) / (a ** 2).sum(1).mean() if with_scale else 1.0
    return scale, rot, md - scale * rot @ ms


def ground_normal(cloud, up_hint):
    """Unit normal of the plane through a sparse cloud (robust: two passes, 3 MAD), towards up_hint."""
    c = np.asarray(cloud)
    keep = np.ones(len(c), dtype=bool)
    for _ in range(2):
        m = c[keep].mean(0)
        _, _, vt = np.linalg.svd(c[keep] - m, full_matrices=False)
        d = np.abs((c - m) @ vt[2])
        keep = d <= 3 * 1.4826 * np.median(d[keep])
    return vt[2] if np.dot(vt[2], up_hint - m) > 0 else -vt[2]


def level(points, n):
    """Plan coordinates of points on the plane of normal n (right-handed e1, e2, n)."""
    m = points.mean(0)
    e1 = np.cross(n, [0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.cross(n, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    return np.column_stack([(points - m) @ e1, (points - m) @ e2])


def fit_similarity_2d(src, dst):
    s, rot, t = umeyama(src, dst)
    return lambda p: (s * (rot @ np.atleast_2d(p).T)).T + t, s


def fit_affine_2d(src, dst):
    a = np.column_stack([src, np.ones(len(src))])
    coef = np.linalg.lstsq(a, dst, rcond=None)[0]
    return lambda p: np.column_stack([np.atleast_2d(p), np.ones(len(np.atleast_2d(p)))]) @ coef


def plan_fit(names, plan, survey_en, fitter, parameters):
    """Residuals survey - fit(plan) per marker, RMS, sigma0 with its degrees of freedom, LOO."""
    f = fitter(plan, survey_en)
    f = f[0] if isinstance(f, tuple) else f
    res = survey_en - f(plan)
    rows = {}
    for i, n in enumerate(names):
        rows[n] = {"dE_m": float(res[i, 0]), "dN_m": float(res[i, 1])}
        keep = [j for j in range(len(names)) if j != i]
        if len(keep) * 2 > parameters:
            g = fitter(plan[keep], survey_en[keep])
            g = g[0] if isinstance(g, tuple) else g
            r = survey_en[i] - g(plan[i])[0]
            rows[n]["loo_dE_m"], rows[n]["loo_dN_m"] = float(r[0]), float(r[1])
    sq = (res ** 2).sum()
    dof = 2 * len(names) - parameters
    loo = [math.hypot(r["loo_dE_m"], r["loo_dN_m"]) for r in rows.values() if "loo_dE_m" in r]
    return {"markers": rows, "plan_rmse_m": float(math.sqrt(sq / len(names))),
            "sigma0_m": float(math.sqrt(sq / dof)) if dof > 0 else None, "dof": dof,
            "leave_one_out_plan_rmse_m": float(math.sqrt(np.mean(np.square(loo)))) if loo else None}


def tool_analysis(cams, survey, clicks, cloud=None):
    """Every marker triangulated with one tool's cameras and fitted to the survey."""
    if not cams:
        return None
    per = {name: marker_rays(cams, clicks[name]) for name in sorted(clicks)}
    names = [n for n in sorted(per) if per[n]["triangulated"]]
    out = {"per_marker": per}
    if len(names) < 3:
        return out
    pts = np.array([per[n]["point"] for n in names])
    up = np.mean([c.centre for c in cams.values()], axis=0)  # the kite is above the beach
    # The vertical: the plane of the tool's whole sparse cloud (the beach), or the tool's
    # own z axis when it has georeferenced (strata: site frame, z up). Not the markers'
    # own plane: copr's markers lie near a line along the beach, which leaves the plane's
    # tilt about that line undetermined.
    normal = ground_normal(list(cloud.values()), up) if cloud else np.array([0.0, 0.0, 1.0])
    plan = level(pts, normal)
    sv = np.linalg.svd(pts - pts.mean(0), compute_uv=False)
    out["markers_spread_m"] = sv.tolist()  # singular values: a small 2nd one = nearly collinear
    _, _, vt = np.linalg.svd(pts - pts.mean(0))
    out["markers_plane_tilt_deg"] = math.degrees(math.acos(min(1.0, abs(float(vt[2] @ normal)))))
    en = np.array([survey[n][:2] for n in names])
    en0 = en.mean(0)  # fit in a local frame (never raw UTM in the least squares)
    out["fit"] = plan_fit(names, plan, en - en0, fit_similarity_2d, 4)
    out["fit"]["scale"] = float(fit_similarity_2d(plan, en - en0)[1])
    out["affine_fit"] = plan_fit(names, plan, en - en0, fit_affine_2d, 6)
    out["levelling"] = "sparse cloud plane" if cloud else "tool's z axis"
    out["levelling_normal"] = normal.tolist()
    return out


def tools_agreement(a, b):
    """The two tools' triangulated markers against each other after a 3D similarity (metres of b)."""
    if not a or not b:
        return None
    names = [n for n in sorted(a["per_marker"]) if a["per_marker"][n].get("triangulated")
             and b["per_marker"].get(n, {}).get("triangulated")]
    if len(names) < 3:
        return None
    pa = np.array([a["per_marker"][n]["point"] for n in names])
    pb = np.array([b["per_marker"][n]["point"] for n in names])
    s, rot, t = umeyama(pa - pa.mean(0), pb - pb.mean(0))
    r = np.linalg.norm((s * (rot @ (pa - pa.mean(0)).T)).T + t - (pb - pb.mean(0)), axis=1)
    return {"markers": names, "residual_m": dict(zip(names, map(float, r))),
            "rmse_m": float(np.sqrt((r ** 2).mean()))}


def strata_own(quality):
    """strata's own marker residuals and decisions from `process --json`."""
    if not quality:
        return None
    out = {}
    for m in quality.get("markers", []):
        out[m["marker"]] = {
            "role": m.get("role"), "triangulated": m.get("triangulated"), "images": m.get("images"),
            "dE_m": m.get("dE"), "dN_m": m.get("dN"),
            "loo": m.get("leave_one_out"),
            "to_rays_px": {o["image"]: o.get("to_rays_px") for o in m.get("observations", [])},
            "dropped": [o["image"] for o in m.get("observations", []) if o.get("dropped")]}
    return {"markers": out, "rejected": quality.get("rejected_markers"),
            "unusable": quality.get("unusable_markers"), "blunders": quality.get("blunders"),
            "control_rmse": quality.get("control_rmse"), "leave_one_out_rmse": quality.get("leave_one_out_rmse"),
            "message": quality.get("georeference_message")}


def copr_analysis(gcp_list, strata_cams, strata_quality, colmap_cams, colmap_points):
    survey, clicks = read_gcp_list(gcp_list)
    st = tool_analysis(strata_cams, survey, clicks)
    co = tool_analysis(colmap_cams, survey, clicks, colmap_points)
    return {"method": "bench/markers.py (module docstring)", "click_outlier_px": CLICK_OUTLIER_PX,
            "colmap": co, "strata": st, "strata_own": strata_own(strata_quality),
            "colmap_vs_strata_markers": tools_agreement(co, st)}


def print_marker_table(m):
    def f(v, d=2):
        return "-" if v is None else f"{v:.{d}f}"

    print("  markers triangulated from the clicks with each tool's cameras, plan similarity to the survey")
    print(f"  {'marker':<7} {'tool':<7} {'rays px (to others)':<28} {'dE m':>7} {'dN m':>7} {'LOO m':>6}"
          f"  strata's own: role dE dN")
    own = (m.get("strata_own") or {}).get("markers", {})
    for name in sorted(set((m.get("colmap") or {}).get("per_marker", {})) | set(own)):
        for tool in ("colmap", "strata"):
            t = m.get(tool) or {}
            pm = t.get("per_marker", {}).get(name, {})
            fit = (t.get("fit") or {}).get("markers", {}).get(name, {})
            rays = " ".join(f"{f(o.get('residual_px'), 1)}({f(o.get('to_other_rays_px'), 0)})"
                            + ("x" if o.get("dropped") else "") for o in pm.get("observations", []))
            loo = math.hypot(fit["loo_dE_m"], fit["loo_dN_m"]) if "loo_dE_m" in fit else None
            extra = ""
            if tool == "strata" and name in own:
                o = own[name]
                extra = f"  {o['role']} {f(o['dE_m'])} {f(o['dN_m'])}" if o.get("triangulated") else f"  {o['role']} -"
            print(f"  {name:<7} {tool:<7} {rays or '-':<28} {f(fit.get('dE_m')):>7} {f(fit.get('dN_m')):>7}"
                  f" {f(loo):>6}{extra}")
    for tool in ("colmap", "strata"):
        t = m.get(tool) or {}
        if t.get("fit"):
            print(f"  {tool}: plan similarity RMSE {f(t['fit']['plan_rmse_m'])} m over {len(t['fit']['markers'])}"
                  f" markers (sigma0 {f(t['fit']['sigma0_m'])} m, LOO {f(t['fit']['leave_one_out_plan_rmse_m'])} m);"
                  f" 2D affine RMSE {f(t['affine_fit']['plan_rmse_m'])} m")
    a = m.get("colmap_vs_strata_markers")
    if a:
        print(f"  COLMAP vs strata markers after a 3D similarity: RMSE {a['rmse_m']:.3f} m over {len(a['markers'])}")
