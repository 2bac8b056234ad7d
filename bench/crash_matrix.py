#!/usr/bin/python3
"""Crash matrix (docs/reliability.md, "Crash injection").

For every kill point listed in src/core/fault.hpp (kCrashPoints), runs the strata
command that passes it with STRATA_CRASH_AT armed, on a copy of a small synthetic
project in the state that command starts from, and checks:

  killed     the command died by SIGKILL (the point was reached)
  integrity  PRAGMA integrity_check and foreign_key_check of project.gpkg are clean
  media      every photo in media/ still hashes to its SHA-256 name
  products   every product row names a whole file: its size and SHA-256 are the recorded ones
  outputs    an export's --out is either absent or whole (the undisturbed run's bytes)
  rerun      the same command, undisturbed, completes (exit 0) and leaves the project
             (and output) as an undisturbed run from the same start leaves it:
             the same rows, the same product checksums, the same exported bytes;
             with several files (an .obj, its .mtl and atlases), the one naming the
             others is never there without them

The range data (laser scans, a depth sequence) and the finds come from the same
`strata synth` run as the photos, thinned to keep the matrix within minutes; the
calibration file for 'import calibration' is written here.

Prints a table and "N passed, M failed"; writes bench/results/crash-<UTC>.json.

Usage: bench/crash_matrix.py [--sample] [--only SUBSTRING]... [--strata EXE] [--work DIR [--reuse]] [--keep]
  --sample   one or two points per command family (the test suite runs this)
Exit status 0 when every point passed.
"""
import argparse
import datetime
import hashlib
import json
import math
import os
import re
import shutil
import signal
import sqlite3
import struct
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CRS = "EPSG:32636"
PHOTO_WIDTH = 800     # pixels: the synthetic photos
SCAN_STEP_MRAD = 16   # the synthetic scans' angular step: a few thousand points a scan, enough for ICP
DEPTH_FRAMES = 8      # the synthetic depth sequence: enough to track, few to register in seconds
SCANS = [("S1.xyz", 0), ("S1_turned_120.xyz", 120), ("S1_turned_240.xyz", 240)]  # name, degrees about z

# Points the test suite runs (--sample): one or two per command family, a few minutes in all.
SAMPLE = [
    "init.before_commit",
    "import.photos.media_part_written",
    "import.markers.observation_written",
    "process.align.before_commit",
    "process.dense.swapped",
    "process.products.ortho_written",
    "volume.model_loaded",
    "export.qgis.temp_written",
    "import.scans.row_inserted",
    "import.finds.find_written",
]


def crash_points():
    """(name, where) of every point in kCrashPoints, in the header's order."""
    text = open(os.path.join(ROOT, "src", "core", "fault.hpp"), encoding="utf-8").read()
    body = text[text.index("kCrashPoints[] = {"):]
    body = body[: body.index("};")]
    return re.findall(r'\{"([a-z_.]+)",\s*"([^"]*)"\}', body)


def points_in_sources():
    """{name: first file} of every point the code passes by a literal name (fault::point("..."),
    StagedFiles::swap_in("...")): a name missing from kCrashPoints makes its command stop
    with an internal error whenever STRATA_CRASH_AT is set."""
    used = {}
    for top in ("src", "importers", "exporters"):
        for dirpath, _, files in os.walk(os.path.join(ROOT, top)):
            for f in files:
                if not f.endswith(".cpp"):
                    continue
                path = os.path.join(dirpath, f)
                text = open(path, encoding="utf-8", errors="replace").read()
                for name in re.findall(r'(?:fault::point|swap_in)\(\s*"([a-z_.]+)"', text):
                    used.setdefault(name, os.path.relpath(path, ROOT))
    return used


# ---- the project states a command starts from --------------------------------------

class Project:
    """The synthetic data, the prepared states, and the one working site folder.

    Every run happens in the same folder (WORK/site): the dense stage keys its cache
    by the photos' paths, so a copy elsewhere would recompute it and hide nothing but
    cost minutes."""

    def __init__(self, strata, work):
        self.strata = strata
        self.work = work
        self.data = os.path.join(work, "data")
        self.site = os.path.join(work, "site")
        self.states = os.path.join(work, "states")
        self.out = os.path.join(work, "out")
        os.makedirs(self.states, exist_ok=True)

    def run(self, args, crash=None, check=True):
        env = dict(os.environ)
        env.pop("STRATA_CRASH_AT", None)
        if crash:
            env["STRATA_CRASH_AT"] = crash
        r = subprocess.run([self.strata, "-q"] + args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           text=True)
        if check and r.returncode != 0:
            raise RuntimeError(f"strata {' '.join(args)}: exit {r.returncode}: {r.stderr.strip()[-400:]}")
        return r

    def photos(self, layer):
        d = os.path.join(self.data, "photos", layer)
        return sorted(os.path.join(d, f) for f in os.listdir(d))

    def layers(self):
        rows = []
        with open(os.path.join(self.data, "layers.csv")) as f:
            next(f)
            for line in f:
                layer, unit = line.strip().split(",")[:2]
                rows.append((layer, unit))
        return rows

    def units(self):
        with open(os.path.join(self.data, "units.csv")) as f:
            next(f)
            return [line.strip().split(",")[0] for line in f if line.strip()]

    def relations(self):
        with open(os.path.join(self.data, "relations.csv")) as f:
            next(f)
            return [line.strip().split(",")[:3] for line in f if line.strip()]

    def save(self, state):
        dst = os.path.join(self.states, state)
        shutil.rmtree(dst, ignore_errors=True)
        shutil.copytree(self.site, dst, symlinks=True)  # copy2: times kept (cache keys use them)

    def restore(self, state):
        shutil.rmtree(self.site, ignore_errors=True)
        shutil.rmtree(self.out, ignore_errors=True)
        os.makedirs(self.out)
        if state != "nothing":
            shutil.copytree(os.path.join(self.states, state), self.site, symlinks=True)

    def prepare(self, log):
        t = time.time()
        self.run(["synth", self.data, "--size", "small", "--stages", "1", "--photos", "14", "--width",
                  str(PHOTO_WIDTH), "--seed", "5", "--scans", "--scan-step-mrad", str(SCAN_STEP_MRAD), "--depth",
                  "--depth-frames", str(DEPTH_FRAMES)])
        self.write_calibration()
        log(f"synthetic data in {time.time() - t:.0f} s")
        shutil.rmtree(self.site, ignore_errors=True)
        self.run(["init", self.site, "--crs", CRS])
        self.save("initialised")
        for code in self.units():
            self.run(["unit", "add", self.site, code])
        self.save("units")
        for a, kind, b in self.relations():
            self.run(["relation", "add", self.site, a, kind, b])
        for layer, unit in self.layers():
            self.run(["layer", "add", self.site, layer, "--unit", unit])
        self.save("recorded")
        for layer, _ in self.layers():
            self.run(["import", "photos", self.site, "--layer", layer] + self.photos(layer))
        self.save("photos")
        self.run(["import", "markers", self.site, os.path.join(self.data, "markers.csv")])
        self.run(["import", "markers", self.site, os.path.join(self.data, "gcp_list.txt")])
        self.save("imported")
        for until, state in (("sparse", "sparse"), ("dense", "dense"), ("products", "processed")):
            t = time.time()
            self.run(["process", self.site, "--all", "--until", until])
            log(f"process --until {until}: {time.time() - t:.0f} s")
            self.save(state)
        t = time.time()
        self.run(["volume", self.site] + self.outline())
        log(f"volume: {time.time() - t:.0f} s")
        self.save("volumes")
        layer = self.range_layer()
        self.make_scans(layer)
        self.run(["import", "scan", self.site, "--layer", layer] + self.scans())
        self.save("scans")
        self.run(self.depth_import(layer))
        self.save("depth")

    def range_layer(self):
        """The layer the range data record: the last (the pit and the wall give ICP relief to hold on to)."""
        return self.layers()[-1][0]

    def make_scans(self, layer):
        """Three scans ICP registers on the layer's photo surface: the synthetic station S1
        as it is and turned 120 and 240 degrees about the vertical (a levelled scanner
        anywhere). The generator's other stations overlap this small project's photo
        surface too little. Written as x y z text, millimetres kept."""
        src = os.path.join(self.data, "scans", layer, "S1.ply")
        data = open(src, "rb").read()
        head_end = data.index(b"end_header\n") + len(b"end_header\n")
        header = data[:head_end].decode("ascii").splitlines()
        count = int(next(line.split()[2] for line in header if line.startswith("element vertex")))
        props = [line.split()[2] for line in header if line.startswith("property float")]
        assert "binary_little_endian" in header[1] and props[:3] == ["x", "y", "z"], header
        stride = 4 * len(props)
        points = [struct.unpack_from("<3f", data, head_end + i * stride) for i in range(count)]
        os.makedirs(os.path.join(self.data, "range"), exist_ok=True)
        for name, turn in SCANS:
            c, s = math.cos(math.radians(turn)), math.sin(math.radians(turn))
            with open(os.path.join(self.data, "range", name), "w") as out:
                for x, y, z in points:
                    out.write(f"{c * x - s * y:.4f} {s * x + c * y:.4f} {z:.4f}\n")

    def scans(self):
        return [os.path.join(self.data, "range", name) for name, _ in SCANS]

    def depth_import(self, layer):
        d = os.path.join(self.data, "depth", layer)
        frames = sorted(os.path.join(d, "depth", f) for f in os.listdir(os.path.join(d, "depth")))
        return ["import", "depth", self.site, "--layer", layer, "--intrinsics", os.path.join(d, "intrinsics.txt"),
                "--poses", os.path.join(d, "poses_recorded.txt"), "--colour", os.path.join(d, "colour")] + frames

    def write_calibration(self):
        """An OpenCV calibration (YAML) of the synthetic camera's size, for 'import calibration'."""
        w, h = PHOTO_WIDTH, PHOTO_WIDTH * 2 // 3
        f = 0.9 * w
        with open(os.path.join(self.data, "lens.yml"), "w") as out:
            out.write("%YAML:1.0\n---\n"
                      f"image_width: {w}\nimage_height: {h}\n"
                      "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
                      f"   data: [ {f:.1f}, 0., {(w - 1) / 2}, 0., {f:.1f}, {(h - 1) / 2}, 0., 0., 1. ]\n"
                      "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 4\n   dt: d\n"
                      "   data: [ -0.05, 0.01, 0., 0. ]\n")

    def outline(self):
        f = os.path.join(self.data, "trench_outline.geojson")
        return ["--outline", f] if os.path.exists(f) else []


# ---- scenarios: a start state and the command run from it -----------------------------

class Scenario:
    """`entry`: the output file that names the others (an .obj its .mtl and atlases):
    when it is there, every file of the undisturbed output must be too.
    `done_refusal`: the error by which the command refuses, by design, to do again what
    is already recorded; a rerun refused with it passes when the project already is as
    the undisturbed run leaves it (the killed run had committed)."""

    def __init__(self, name, state, command, out=None, entry=None, done_refusal=None):
        self.name, self.state, self.command, self.out, self.entry = name, state, command, out, entry
        self.done_refusal = done_refusal


def scenarios(p):
    layer, unit = p.layers()[0]
    rlayer = p.range_layer()
    s, o = p.site, p.out
    units = p.units()
    return {
        "init": Scenario("init", "nothing", lambda: ["init", s, "--crs", CRS]),
        "unit": Scenario("unit", "initialised", lambda: ["unit", "add", s, "999", "--type", "cut"]),
        "layer": Scenario("layer", "recorded", lambda: ["layer", "add", s, "L9", "--unit", unit]),
        # Two units the generator's matrix leaves unordered (101 above both; 104 above 102, which 103 cuts).
        "relation": Scenario("relation", "recorded", lambda: ["relation", "add", s, units[2], "abuts", units[3]]),
        "photos": Scenario("photos", "recorded", lambda: ["import", "photos", s, "--layer", layer] + p.photos(layer)),
        "markers": Scenario("markers", "photos", lambda: ["import", "markers", s, os.path.join(p.data, "gcp_list.txt")]),
        "align": Scenario("align", "imported", lambda: ["process", s, "--layer", layer, "--until", "sparse"]),
        "dense": Scenario("dense", "sparse", lambda: ["process", s, "--layer", layer, "--until", "dense"]),
        "products": Scenario("products", "dense", lambda: ["process", s, "--layer", layer]),
        # A second volume run with another threshold: the thickness rasters and rows exist and are replaced.
        "volume": Scenario("volume", "processed", lambda: ["volume", s] + p.outline()),
        "revolume": Scenario("revolume", "volumes", lambda: ["volume", s, "--threshold", "0.006"] + p.outline()),
        "cameras": Scenario("cameras", "processed",
                            lambda: ["export", "cameras", s, "--layer", layer, "--out", f"{o}/cameras.csv"],
                            out="cameras.csv"),
        "mesh": Scenario("mesh", "processed", lambda: ["export", "mesh", s, "--layer", layer, "--out", f"{o}/mesh.ply"],
                         out="mesh.ply"),
        "points": Scenario("points", "processed",
                           lambda: ["export", "points", s, "--layer", layer, "--out", f"{o}/points.ply"],
                           out="points.ply"),
        "dtm": Scenario("dtm", "processed",
                        lambda: ["export", "dtm", s, "--layer", layer, "--cell", "0.01", "--out", f"{o}/dtm.tif"],
                        out="dtm.tif"),
        "qgs": Scenario("qgs", "processed", lambda: ["export", "qgis", s, "--out", f"{o}/site.qgs"], out="site.qgs"),
        "qgz": Scenario("qgz", "processed", lambda: ["export", "qgis", s, "--out", f"{o}/site.qgz"], out="site.qgz"),
        "grass": Scenario("grass", "processed", lambda: ["export", "grass", s, "--out", f"{o}/grass"], out="grass"),
        "report": Scenario("report", "volumes", lambda: ["report", s, "--out", f"{o}/report.html"], out="report.html"),
        # The unit register and the relations as spreadsheets, into a project without them.
        "units": Scenario("units", "initialised", lambda: ["import", "units", s, os.path.join(p.data, "units.csv")]),
        "relations": Scenario("relations", "units",
                              lambda: ["import", "relations", s, os.path.join(p.data, "relations.csv")]),
        "finds": Scenario("finds", "volumes", lambda: ["import", "finds", s, os.path.join(p.data, "finds.csv")]),
        "find": Scenario("find", "volumes", lambda: ["find", "add", s, "--id", "F99", "--at",
                                                      "734013.5,4174018.5,1450.55", "--unit", unit]),
        "calibration": Scenario("calibration", "photos", lambda: ["import", "calibration", s,
                                                                  os.path.join(p.data, "lens.yml"), "--camera",
                                                                  os.path.basename(p.photos(layer)[0])]),
        "camera": Scenario("camera", "photos", lambda: ["camera", "set", s, os.path.basename(p.photos(layer)[0]),
                                                        "--focal-px", str(0.9 * PHOTO_WIDTH), "--fixed"]),
        # The first layer's three scans, imported unregistered; then registered by ICP on
        # its photo surface, or one of them on the surveyed markers its scanner measured.
        "scan": Scenario("scan", "volumes", lambda: ["import", "scan", s, "--layer", rlayer] + p.scans()),
        "register_scan": Scenario("register_scan", "scans", lambda: ["register", "scan", s, "--layer", rlayer]),
        "register_targets": Scenario("register_targets", "scans", lambda: [
            "register", "scan", s, "--layer", rlayer, "--scan", SCANS[0][0], "--targets",
            os.path.join(p.data, "scans", rlayer, "S1_targets.csv")]),
        # A sequence imported again is refused by design ('give another --sequence name'):
        # killed after its commit, the rerun is refused and the project must already be whole.
        "depth": Scenario("depth", "scans", lambda: p.depth_import(rlayer),
                          done_refusal="already has a depth sequence named"),
        "register_depth": Scenario("register_depth", "depth", lambda: ["register", "depth", s, "--layer", rlayer]),
        "glb": Scenario("glb", "volumes", lambda: ["export", "model", s, "--out", f"{o}/site.glb"], out="site.glb"),
        "obj": Scenario("obj", "processed", lambda: ["export", "model", s, "--layer", layer, "--texture",
                                                     "--atlas-size", "2048", "--out", f"{o}/model/{layer}.obj"],
                        out="model", entry=f"model/{layer}.obj"),
        # The meshes kept whole (no simplification: 100 s of this project's 2 cores for the same writing).
        "viewer": Scenario("viewer", "volumes", lambda: ["export", "viewer", s, "--max-faces", "0", "--coarse-lod", "0",
                                                         "--out", f"{o}/site.html"], out="site.html"),
    }


def runs_for(point, where):
    """The (scenario, STRATA_CRASH_AT) pairs that test a point."""
    fixed = {
        "init.database_created": [("init", None)],
        "init.before_commit": [("init", None)],
        "db.migration_applied": [("init", None)],
        "db.before_commit": [("unit", None), ("photos", None), ("align", None), ("dense", ":1"), ("dense", ":2"),
                             ("products", ":1"), ("products", ":2"), ("volume", None), ("revolume", None),
                             ("scan", None), ("register_depth", None)],
        "db.after_commit": [("markers", None), ("dense", ":1"), ("products", ":3"), ("revolume", None),
                            ("finds", None)],
        # The media store is shared: scans and depth frames pass it too.
        "import.photos.media_part_written": [("photos", None), ("photos", ":3"), ("scan", ":2"), ("depth", ":3")],
        "import.finds.parsed": [("finds", None), ("find", None)],
        "import.finds.find_written": [("finds", None), ("finds", ":3"), ("find", None)],
        "import.finds.before_commit": [("finds", None), ("find", None)],
        "register.scans.fitted": [("register_scan", None), ("register_targets", None)],
        "register.scans.scan_written": [("register_scan", None), ("register_scan", ":3"), ("register_targets", None)],
        "register.scans.before_commit": [("register_scan", None), ("register_targets", None)],
        # Four renames (two atlases, the .mtl, the .obj): after the first atlas, the .mtl, the .obj.
        "export.obj.file_renamed": [("obj", None), ("obj", ":3"), ("obj", ":4")],
        "stratigraphy.unit_before_commit": [("unit", None)],
        "stratigraphy.layer_before_commit": [("layer", None)],
        "stratigraphy.relation_before_commit": [("relation", None)],
        "products.geotiff.temp_written": [("products", None), ("products", ":3"), ("dtm", None)],
        "products.gpkg_raster.table_dropped": [("products", None), ("products", ":2")],
        "process.features.file_temp_written": [("align", None), ("align", ":20")],
        "export.cameras.temp_written": [("cameras", None)],
        "export.copy.temp_written": [("mesh", None), ("points", None)],
        "export.qgis.temp_written": [("qgs", None)],
        "export.qgz.temp_written": [("qgz", None)],
        "export.report.temp_written": [("report", None)],
        "volume.model_loaded": [("volume", None), ("revolume", None)],
        "volume.stored": [("volume", None)],
    }
    if point in fixed:
        return fixed[point]
    prefix = [("import.photos.", "photos"), ("import.markers.", "markers"), ("process.features.", "align"),
              ("process.matching.", "align"), ("process.targets.", "align"), ("process.sfm.", "align"),
              ("process.georeference.", "align"), ("process.align.", "align"), ("process.dense.", "dense"),
              ("process.products.", "products"), ("export.grass.", "grass"), ("import.scans.", "scan"),
              ("import.depth.", "depth"), ("import.units.", "units"), ("import.relations.", "relations"),
              ("import.calibration.", "calibration"), ("camera.set.", "camera"), ("register.depth.", "register_depth"),
              ("export.gltf.", "glb"), ("export.obj.", "obj"), ("export.viewer.", "viewer")]
    for pre, scenario in prefix:
        if point.startswith(pre):
            # A point passed once per item (its description says "one ...", "a ..." or "an ..."):
            # also its third pass, mid-way.
            many = where.startswith(("one ", "a ", "an "))
            return [(scenario, None)] + ([(scenario, ":3")] if many else [])
    return []


# ---- what is checked --------------------------------------------------------------------

def sha256_file(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def db_problems(site):
    db = os.path.join(site, "project.gpkg")
    if not os.path.exists(db):
        return []
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    try:
        problems = []
        ic = [r[0] for r in con.execute("PRAGMA integrity_check")]
        if ic != ["ok"]:
            problems.append("integrity_check: " + "; ".join(ic[:3]))
        fk = con.execute("PRAGMA foreign_key_check").fetchall()
        if fk:
            problems.append(f"foreign_key_check: {len(fk)} row(s), e.g. {fk[0]}")
        return problems
    finally:
        con.close()


def media_problems(site):
    problems = []
    media = os.path.join(site, "media")
    for dirpath, _, files in os.walk(media):
        for f in files:
            if f.endswith(".part"):
                continue  # a copy not yet renamed into the store: not a photo (replaced by the next import)
            stem = f.split(".")[0]
            if not re.fullmatch(r"[0-9a-f]{64}", stem) or sha256_file(os.path.join(dirpath, f)) != stem:
                problems.append(f"media/{os.path.relpath(os.path.join(dirpath, f), media)} does not hash to its name")
    return problems


def product_problems(site):
    db = os.path.join(site, "project.gpkg")
    if not os.path.exists(db):
        return []
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    try:
        rows = con.execute("SELECT kind, path, sha256, bytes FROM products").fetchall()
    finally:
        con.close()
    problems = []
    for kind, path, sha, size in rows:
        f = os.path.join(site, path)
        if not os.path.exists(f):
            problems.append(f"{kind} {path}: recorded, missing")
        elif os.path.getsize(f) != size or sha256_file(f) != sha:
            problems.append(f"{kind} {path}: recorded, but not the recorded file (size or SHA-256)")
    return problems


def report_hash(path):
    """SHA-256 of a report without the facts of the run (when it was generated, how long
    the alignment took): the rest must be reproducible."""
    if not os.path.exists(path):
        return "missing"
    text = open(path, "rb").read().decode("utf-8", "replace")
    text = re.sub(r"generated \d{4}-\d{2}-\d{2} \d{2}:\d{2} UTC", "generated -", text)
    text = re.sub(r"<tr><th>alignment time</th><td>[^<]*</td></tr>", "", text)
    return hashlib.sha256(text.encode()).hexdigest()


def gpkg_hash(path):
    """SHA-256 of a GeoPackage's rows with its write times (gpkg_contents.last_change)
    blanked: GDAL stamps them on every write. A file SQLite cannot read hashes as bytes."""
    try:
        con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
        try:
            h = hashlib.sha256()
            for line in con.iterdump():
                h.update(re.sub(r"\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}(\.\d+)?Z", "-", line).encode())
            return h.hexdigest()
        finally:
            con.close()
    except sqlite3.DatabaseError:
        return sha256_file(path)


def file_hash(path):
    if path.endswith(".html"):
        return report_hash(path)
    if path.endswith(".gpkg"):
        return gpkg_hash(path)
    return sha256_file(path)


def tree_hashes(path):
    """{relative path: sha256} of a file or of every file under a folder."""
    if not os.path.exists(path):
        return {}
    if os.path.isfile(path):
        return {os.path.basename(path): file_hash(path)}
    out = {}
    for dirpath, _, files in os.walk(path):
        for f in files:
            full = os.path.join(dirpath, f)
            out[os.path.relpath(full, path)] = file_hash(full)
    return out


def is_temp(name):
    """A file at its temporary or staged name (x.tmp, x.part, x.tmp3, x.next.glb)."""
    return re.search(r"\.(tmp|part)(\.[a-z]+)?$|\.tmp\d|\.next\.[a-z0-9]+$", name) is not None


def output_problems(out, reference, entry=None):
    """An export's output after a kill: absent, or every file whole (the reference's bytes);
    when the file naming the others (`entry`) is there, every one of them too."""
    problems = []
    found = tree_hashes(out)
    for rel, sha in found.items():
        if is_temp(rel):
            continue
        if rel not in reference:
            problems.append(f"{rel}: not in the undisturbed output")
        elif reference[rel] != sha:
            problems.append(f"{rel}: half-written (differs from the undisturbed output)")
    if entry and entry in found:
        missing = sorted(rel for rel in reference if rel not in found)
        if missing:
            problems.append(f"{entry} is there without " + ", ".join(missing) + ", which it names")
    return problems


def fingerprint(p):
    """What a command leaves: the rows that matter (no ids, no times) and product checksums."""
    db = os.path.join(p.site, "project.gpkg")
    fp = {}
    if os.path.exists(db):
        con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
        q = {
            "units": "SELECT code, type, description FROM units ORDER BY code",
            "relations": "SELECT a.code, r.kind, b.code FROM relations r JOIN units a ON a.id = r.unit_a "
                         "JOIN units b ON b.id = r.unit_b ORDER BY 1, 2, 3",
            "layers": "SELECT l.name, u.code FROM layers l JOIN units u ON u.id = l.unit_id ORDER BY 1",
            "images": "SELECT l.name, i.name, i.sha256, i.media_path, i.bytes FROM images i "
                      "JOIN layers l ON l.id = i.layer_id ORDER BY 1, 2",
            "markers": "SELECT name, e, n, z, sigma_e, kind FROM markers ORDER BY name",
            "observations": "SELECT m.name, i.name, o.x, o.y, o.source FROM observations o "
                            "JOIN markers m ON m.fid = o.marker_id JOIN images i ON i.id = o.image_id ORDER BY 1, 2, 5",
            "reconstructions": "SELECT l.name, r.stage, r.inputs_key FROM reconstructions r "
                               "JOIN layers l ON l.id = r.layer_id ORDER BY 1, 2",
            "poses": "SELECT i.name, p.registered, p.cx_site, p.cy_site, p.cz_site FROM image_poses p "
                     "JOIN images i ON i.id = p.image_id ORDER BY 1",
            "products": "SELECT kind, path, sha256, bytes FROM products ORDER BY path",
            "unit_volumes": "SELECT u.code, v.volume_m3, v.area_m2, v.mean_thickness_m FROM unit_volumes v "
                            "JOIN units u ON u.id = v.unit_id ORDER BY 1",
            "calibrations": "SELECT camera_id, model, fx, fy, cx, cy, k1, k2, k3, k4, p1, p2, fixed, source "
                            "FROM camera_calibrations ORDER BY 1",
            "finds": "SELECT find_id, unit, type, description, e, n, z, source FROM finds ORDER BY 1",
            "finds_extent": "SELECT min_x, min_y, max_x, max_y FROM gpkg_contents WHERE table_name = 'finds'",
            "scans": "SELECT l.name, s.name, s.sha256, s.media_path, s.bytes, s.points, s.sigma_m, s.registration, "
                     "s.transform, s.min_x, s.min_y, s.min_z, s.max_x, s.max_y, s.max_z, s.registered_by, "
                     "s.registered_against, s.registration_rms_m, s.registration_inliers FROM scans s "
                     "JOIN layers l ON l.id = s.layer_id ORDER BY 1, 2",
            "depth_sequences": "SELECT l.name, d.name, d.width, d.height, d.fx, d.fy, d.cx, d.cy, d.depth_scale_m, "
                               "d.noise_k, d.intrinsics_file, d.poses_file FROM depth_sequences d "
                               "JOIN layers l ON l.id = d.layer_id ORDER BY 1, 2",
            "depth_frames": "SELECT q.name, f.frame, f.name, f.sha256, f.media_path, f.bytes, f.valid_pixels, "
                            "f.colour_sha256, f.colour_media_path, f.recorded_pose, f.pose, f.registered_by, "
                            "f.registration_rms_m, f.min_x, f.min_y, f.min_z, f.max_x, f.max_y, f.max_z "
                            "FROM depth_frames f JOIN depth_sequences q ON q.id = f.sequence_id ORDER BY 1, 2",
        }
        try:
            for k, sql in q.items():
                fp[k] = [list(r) for r in con.execute(sql).fetchall()]
        finally:
            con.close()
        # A report's recorded checksum covers the run's time; compare its content without it.
        fp["products"] = [[kind, path, report_hash(os.path.join(p.site, path)) if kind == "report" else sha,
                            None if kind == "report" else size]
                          for kind, path, sha, size in fp["products"]]
    fp["out"] = tree_hashes(p.out)
    return fp


def differences(a, b):
    """What differs between two fingerprints, with detail for the poses and products."""
    out = []
    for k in sorted(set(a) | set(b)):
        x, y = a.get(k), b.get(k)
        if x == y:
            continue
        if k == "poses" and x and y and len(x) == len(y):
            d = max(max(abs((p[i] or 0) - (q[i] or 0)) for i in (2, 3, 4)) for p, q in zip(x, y))
            reg = sum(p[1] != q[1] for p, q in zip(x, y))
            out.append(f"poses (centres up to {d * 1000:.3f} mm apart, {reg} registration(s) differ)")
        elif k == "products" and x is not None and y is not None:
            px, py = {r[1]: r[2] for r in x}, {r[1]: r[2] for r in y}
            diff = sorted(p for p in set(px) | set(py) if px.get(p) != py.get(p))
            out.append("products (" + ", ".join(diff[:6]) + (" ..." if len(diff) > 6 else "") + ")")
        else:
            out.append(k)
    return out


# ---- the matrix ----------------------------------------------------------------------------

def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sample", action="store_true", help="one or two points per command family")
    ap.add_argument("--only", action="append", default=[], help="points whose name contains this (repeatable)")
    ap.add_argument("--strata", default=os.path.join(ROOT, "build", "src", "cli", "strata"))
    ap.add_argument("--work", help="scratch folder (default: a new one under /tmp)")
    ap.add_argument("--keep", action="store_true", help="keep the scratch folder")
    ap.add_argument("--reuse", action="store_true", help="reuse the states a previous run prepared in --work")
    ap.add_argument("--results", default=os.path.join(ROOT, "bench", "results"))
    args = ap.parse_args()

    points = crash_points()
    chosen = [(n, w) for n, w in points if (not args.sample or n in SAMPLE)
              and (not args.only or any(s in n for s in args.only))]
    work = args.work or tempfile.mkdtemp(prefix="strata-crash-")
    os.makedirs(work, exist_ok=True)
    p = Project(os.path.abspath(args.strata), os.path.abspath(work))
    log = lambda m: print(f"[crash] {m}", flush=True)
    started = time.time()
    log(f"{len(points)} points listed, {len(chosen)} chosen; work in {work}")
    if args.reuse and os.path.isdir(os.path.join(p.states, "volumes")):
        log(f"states reused from {p.states}")
    else:
        p.prepare(log)
    log(f"states prepared in {time.time() - started:.0f} s")
    scen = scenarios(p)

    references = {}

    def reference(name):
        if name not in references:
            sc = scen[name]
            p.restore(sc.state)
            t = time.time()
            p.run(sc.command())
            references[name] = fingerprint(p)
            log(f"reference {name}: {time.time() - t:.1f} s")
        return references[name]

    results = []
    listed = {n for n, _ in points}
    for name, where_used in sorted(points_in_sources().items()):
        if name not in listed and (not args.only or any(s in name for s in args.only)):
            results.append({"point": name, "run": "-", "passed": False,
                            "failures": [f"passed in {where_used} but not in kCrashPoints (core/fault.hpp)"]})
            log(f"FAIL {name}: passed in {where_used} but not in kCrashPoints")
    for name, where in chosen:
        runs = runs_for(name, where)
        if not runs:
            results.append({"point": name, "run": "-", "passed": False, "failures": ["no scenario runs this point"]})
            continue
        for sc_name, hit in runs:
            sc = scen[sc_name]
            spec = name + (hit or "")
            ref = reference(sc_name)
            failures, notes = [], []
            t = time.time()
            p.restore(sc.state)
            r = p.run(sc.command(), crash=spec, check=False)
            killed = r.returncode == -signal.SIGKILL
            if not killed:
                failures.append(f"not killed (exit {r.returncode}): the point was not reached"
                                + (f"; stderr: {r.stderr.strip()[-200:]}" if r.returncode else ""))
            else:
                failures += db_problems(p.site) + media_problems(p.site) + product_problems(p.site)
                if sc.out:
                    failures += output_problems(p.out, ref["out"], sc.entry)
                r2 = p.run(sc.command(), check=False)
                refused_done = r2.returncode != 0 and sc.done_refusal and sc.done_refusal in r2.stderr
                if r2.returncode != 0 and not refused_done:
                    failures.append(f"rerun failed (exit {r2.returncode}): {r2.stderr.strip()[-300:]}")
                else:
                    if refused_done:
                        notes.append("rerun refused by design (the killed run had committed): " + sc.done_refusal)
                    failures += ["after the rerun: " + x for x in db_problems(p.site) + media_problems(p.site)
                                 + product_problems(p.site)]
                    diff = differences(fingerprint(p), ref)
                    if diff:
                        failures.append("rerun differs from the undisturbed run in: " + ", ".join(diff))
                    leftovers = [f for f in tree_hashes(p.out) if is_temp(f)]
                    if leftovers:
                        failures.append("temporary files left in the output: " + ", ".join(leftovers))
            results.append({"point": name, "run": f"{sc_name}{hit or ''}", "where": where, "passed": not failures,
                            "failures": failures, "seconds": round(time.time() - t, 1)}
                           | ({"notes": notes} if notes else {}))
            status = "pass" if not failures else "FAIL"
            log(f"{status} {spec:<46} {sc_name:<9} {time.time() - t:5.1f} s" +
                "".join("\n        " + x for x in failures + notes))

    passed = sum(r["passed"] for r in results)
    failed = len(results) - passed
    distinct = len({r["point"] for r in results if r["passed"]})
    print()
    print(f"| point | command | result | s |")
    print(f"| --- | --- | --- | ---: |")
    for r in results:
        res = "pass" if r["passed"] else "FAIL: " + "; ".join(r["failures"])
        print(f"| {r['point']} | {r['run']} | {res} | {r.get('seconds', '')} |")
    print()
    print(f"{passed} passed, {failed} failed ({distinct} distinct points passed, {len(results)} runs, "
          f"{time.time() - started:.0f} s)")
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    os.makedirs(args.results, exist_ok=True)
    out = os.path.join(args.results, f"crash-{stamp}{'-sample' if args.sample else ''}.json")
    with open(out, "w") as f:
        json.dump({"time": stamp, "sample": args.sample, "passed": passed, "failed": failed,
                   "distinct_points_passed": distinct, "seconds": round(time.time() - started),
                   "results": results}, f, indent=1)
    print(f"wrote {out}")
    if not args.keep and not args.work:
        shutil.rmtree(work, ignore_errors=True)
    return 0 if failed == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
