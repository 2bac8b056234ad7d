#!/usr/bin/env bash
# Writes the seed inputs of every fuzz target into tests/fuzz/corpus/<target>/
# (seed_* files; inputs the fuzzer found are kept beside them under their hash).
# Needs python3, gdal-bin and sqlite3, and a built `strata` for the project seeds:
#   tests/fuzz/make_seeds.sh [path/to/strata]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
strata=${1:-$here/../../build/src/cli/strata}
corpus=$here/corpus
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$corpus"/{markers_csv,markers_odm,photo,calibration,ply,footprint,target_names,project}

# ---- text formats: marker files, calibrations, outlines, target names ----------
python3 - "$corpus" <<'PY'
import struct, sys, pathlib
c = pathlib.Path(sys.argv[1])
def put(target, name, data):
    (c / target / ("seed_" + name)).write_bytes(data if isinstance(data, bytes) else data.encode())

put("markers_csv", "positional.csv", "GCP1,734001.1,4174002.2,1450.3\nGCP2,734005.1,4174002.2,1450.1,0.003,check\n")
put("markers_csv", "header_semicolon.txt", "# total station export\nname;E;N;Z;sigma;kind\nGCP3;734003.0;4174001.0;1449.9;0.005;control\nCP1;734004.0;4174003.0;1449.8;;cp\n")
put("markers_csv", "tab.txt", "GCP4\t734003.5\t4174004.0\t1450.0\n")
put("markers_csv", "spaces_bom.txt", "\ufeffGCP5   734002.5   4174004.5   1450.0\r\nGCP6 734002.7 4174004.9 1450.2 0.02 gcp\r\n")
put("markers_csv", "geographic_header.csv", "point,lon,lat,height,accuracy,use\n\"north peg\",33.25,37.72,1450.0,0.01,checkpoint\n")
put("markers_csv", "odm_like.txt", "EPSG:32636\n734001.1 4174002.2 1450.3 1200.5 800.25 IMG_0001.JPG GCP1\n")

put("markers_odm", "named.txt", "EPSG:32636\n734001.1 4174002.2 1450.3 1200.5 800.25 IMG_0001.JPG GCP1\n734001.1 4174002.2 1450.3 1310 760 IMG_0002.JPG GCP1\n734005.1 4174002.2 1450.1 2000 1500 IMG_0002.JPG GCP2\n")
put("markers_odm", "unnamed_proj.txt", "+proj=utm +zone=36 +datum=WGS84 +units=m +no_defs\n734001.1\t4174002.2\t1450.3\t1200.5\t800.25\t/data/images/IMG_0003.JPG\n734001.1\t4174002.2\t1450.3\t900\t700\tIMG_0001.JPG\n")
put("markers_odm", "wgs84_missing_image.txt", "WGS84\n33.2501 37.7201 1450.3 1200.5 800.25 IMG_0001.JPG GCP7\n33.2502 37.7202 1450.1 10 20 OTHER_PHOTO.JPG GCP8\n")

put("calibration", "opencv.yml", """%YAML:1.0
---
image_width: 160
image_height: 120
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 150., 0., 79.5, 0., 150., 59.5, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ -0.2, 0.07, 0.001, -0.002, 0.01 ]
""")
put("calibration", "opencv_fisheye.yml", """%YAML:1.0
---
image_width: 1920
image_height: 1080
fisheye_model: 1
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 900., 0., 959.5, 0., 900., 539.5, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 4
   cols: 1
   dt: d
   data: [ 0.01, -0.002, 0.0003, 0. ]
""")
put("calibration", "opencv.xml", """<?xml version="1.0"?>
<opencv_storage>
<image_width>160</image_width>
<image_height>120</image_height>
<camera_matrix type_id="opencv-matrix">
  <rows>3</rows><cols>3</cols><dt>d</dt>
  <data>150. 0. 79.5 0. 150. 59.5 0. 0. 1.</data></camera_matrix>
<distortion_coefficients type_id="opencv-matrix">
  <rows>1</rows><cols>8</cols><dt>f</dt>
  <data>-0.2 0.07 0. 0. 0. 0. 0. 0.</data></distortion_coefficients>
<distortion_model>plumb_bob</distortion_model>
</opencv_storage>
""")
put("calibration", "opencv.json", '{"image_width": 160, "image_height": 120, "camera_matrix": {"type_id": "opencv-matrix", "rows": 3, "cols": 3, "dt": "d", "data": [150.0, 0.0, 79.5, 0.0, 150.0, 59.5, 0.0, 0.0, 1.0]}}\n')
put("calibration", "metashape_frame.xml", """<?xml version="1.0" encoding="UTF-8"?>
<calibration>
  <projection>frame</projection>
  <width>160</width>
  <height>120</height>
  <f>150</f>
  <cx>1.5</cx>
  <cy>-2.25</cy>
  <b1>0.75</b1>
  <b2>0.01</b2>
  <k1>-0.11</k1>
  <k2>0.06</k2>
  <k3>-0.012</k3>
  <k4>0</k4>
  <p1>0.0012</p1>
  <p2>-0.0021</p2>
  <date>2026-11-30T10:00:00Z</date>
</calibration>
""")
put("calibration", "metashape_fisheye.xml", "<?xml version=\"1.0\"?>\n<calibration><projection>fisheye</projection><width>4000</width><height>3000</height><f>1800</f><k1>0.01</k1><k4>0.0001</k4></calibration>\n")
put("calibration", "metashape_cameras.xml", """<document><chunk><sensors><sensor id="0">
<calibration type="frame" class="initial"><resolution width="160" height="120"/><f>140</f></calibration>
<calibration type="frame" class="adjusted"><resolution width="160" height="120"/><f>152.5</f><cx>-1</cx><cy>2</cy><k1>-0.1</k1></calibration>
</sensor></sensors></chunk></document>
""")

ring = "[[734001.0, 4174001.0], [734009.5, 4174001.0], [734009.5, 4174006.0], [734001.0, 4174006.0], [734001.0, 4174001.0]]"
put("footprint", "polygon.geojson", '{"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {"unit": "101"}, "geometry": {"type": "Polygon", "coordinates": [' + ring + ']}}]}\n')
put("footprint", "multipolygon_crs.geojson", '{"type": "FeatureCollection", "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::32636"}}, "features": [{"type": "Feature", "properties": null, "geometry": {"type": "MultiPolygon", "coordinates": [[' + ring + ', [[734003, 4174003], [734004, 4174003], [734004, 4174004], [734003, 4174003]]]]}}]}\n')
put("footprint", "point_then_polygon.geojson", '{"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {}, "geometry": {"type": "Point", "coordinates": [734001, 4174001]}}, {"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [[[734001, 4174001, 99.5], [734002, 4174001, 99.5], [734002, 4174002, 99.5]]]}}]}\n')
put("footprint", "bare_geometry.geojson", '{"type": "Polygon", "coordinates": [' + ring + ']}\n')

put("target_names", "names.txt", "GCP{id:03}\n3=GCP_A, 7=north peg,11 = GCP_C\n")
put("target_names", "rule_only.txt", "M{id}")
put("target_names", "empty_rule.txt", "\n0=origin,,12=east")

# reader.ply: what writer.ply writes (double CRS coordinates, colour, normals) and
# a float site-frame mesh with an offset comment.
def ply(double, colour, normal, verts, faces, extra_header=""):
    t = "double" if double else "float"
    h = "ply\nformat binary_little_endian 1.0\ncomment generated by strata (dense)\ncomment crs EPSG:32636\n" + extra_header
    h += f"element vertex {len(verts)}\nproperty {t} x\nproperty {t} y\nproperty {t} z\n"
    if normal: h += "property float nx\nproperty float ny\nproperty float nz\n"
    if colour: h += "property uchar red\nproperty uchar green\nproperty uchar blue\n"
    h += f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    b = bytearray(h.encode())
    for i, v in enumerate(verts):
        b += struct.pack("<3d" if double else "<3f", *v)
        if normal: b += struct.pack("<3f", 0.0, 0.0, 1.0)
        if colour: b += bytes([i * 40 % 256, 128, 255])
    for f in faces:
        b += struct.pack("<B3i", 3, *f)
    return bytes(b)
quad = [(734001.0, 4174001.0, 1450.0), (734002.0, 4174001.0, 1450.1), (734002.0, 4174002.0, 1450.2), (734001.0, 4174002.0, 1450.0)]
put("ply", "crs_colour_normals.ply", ply(True, True, True, quad, [(0, 1, 2), (0, 2, 3)]))
local = [(x - 734000, y - 4174000, z - 1450) for x, y, z in quad]
put("ply", "site_frame_float.ply", ply(False, False, False, local, [(0, 1, 2), (2, 3, 0)], "comment strata_offset 734000.000000 4174000.000000 1450.000000\n"))
put("ply", "points_only.ply", ply(False, True, False, local, []))
PY

# ---- photos: JPEG with EXIF (camera, focal lengths, time), PNG, TIFF -----------------
python3 - "$tmp/grey.pgm" <<'PY'
import sys
w, h = 64, 48
open(sys.argv[1], "wb").write(f"P5\n{w} {h}\n255\n".encode() + bytes((x * 4 + y * 3) % 256 for y in range(h) for x in range(w)))
PY
exif=(-co WRITE_EXIF_METADATA=YES -mo EXIF_Make=Canon -mo "EXIF_Model=Canon EOS 80D"
      -mo "EXIF_FocalLength=(24)" -mo "EXIF_FocalLengthIn35mmFilm=38"
      -mo "EXIF_DateTimeOriginal=2026:06:14 09:31:05" -mo "EXIF_PixelXDimension=6000"
      -mo "EXIF_PixelYDimension=4000" -mo "EXIF_FocalPlaneXResolution=(4000)" -mo "EXIF_FocalPlaneResolutionUnit=3")
gdal_translate -q -of JPEG "${exif[@]}" "$tmp/grey.pgm" "$corpus/photo/seed_exif.jpg"
gdal_translate -q -of JPEG "$tmp/grey.pgm" "$corpus/photo/seed_no_exif.jpg"
gdal_translate -q -of PNG "$tmp/grey.pgm" "$corpus/photo/seed_grey.png"
gdal_translate -q -of GTiff "$tmp/grey.pgm" "$corpus/photo/seed_grey.tif"
rm -f "$corpus"/photo/*.aux.xml

# ---- project.gpkg: strata's own, and the ways someone else's may differ --------------
"$strata" init "$tmp/site" --crs EPSG:32636 --name seed >/dev/null
"$strata" unit add "$tmp/site" 101 >/dev/null
"$strata" layer add "$tmp/site" L1 --unit 101 >/dev/null
printf 'GCP1,734001.1,4174002.2,1450.3\nGCP2,734005.1,4174002.2,1450.1,0.003,check\n' >"$tmp/m.csv"
"$strata" import markers "$tmp/site" "$tmp/m.csv" >/dev/null
db=$tmp/site/project.gpkg
# The smallest page size keeps the seeds small (a few dozen KB) for the fuzzer.
sqlite3 "$db" "PRAGMA journal_mode=DELETE; PRAGMA page_size=512; VACUUM;" >/dev/null
variant() {  # variant NAME SQL: a copy of the project with SQL applied
  cp "$db" "$tmp/v.gpkg"
  sqlite3 "$tmp/v.gpkg" "$2" >/dev/null
  cp "$tmp/v.gpkg" "$corpus/project/seed_$1.gpkg"
}
cp "$db" "$corpus/project/seed_strata.gpkg"
variant newer_schema "UPDATE strata_meta SET value='99' WHERE key='schema_version'"
variant older_schema "UPDATE strata_meta SET value='6' WHERE key='schema_version'"
variant schema_not_a_number "UPDATE strata_meta SET value='seven' WHERE key='schema_version'"
variant no_site "DROP TABLE site"
variant no_meta "DROP TABLE strata_meta"
variant markers_altered "ALTER TABLE markers DROP COLUMN sigma_e; ALTER TABLE markers RENAME COLUMN kind TO role"
variant site_text_origin "PRAGMA ignore_check_constraints=1; UPDATE site SET origin_e='north', srs_id='x'"
variant not_gpkg "PRAGMA application_id=0"
# A GeoPackage of another program (GDAL), and a file that is not SQLite at all.
ogr2ogr -q -f GPKG "$tmp/other.gpkg" "$corpus/footprint/seed_polygon.geojson"
sqlite3 "$tmp/other.gpkg" "PRAGMA page_size=512; VACUUM;" >/dev/null
cp "$tmp/other.gpkg" "$corpus/project/seed_gdal_geopackage.gpkg"
printf 'this is not a database\n' >"$corpus/project/seed_text.gpkg"
for d in "$corpus"/*/; do echo "$(basename "$d"): $(ls "$d" | wc -l) files, $(du -sk "$d" | cut -f1) KB"; done

# ---- surfaces (geotiff) and the volume and section options --------------------
mkdir -p "$corpus"/{geotiff,section_options,volume_options}
python3 - "$tmp" <<'PY'
import sys, pathlib
t = pathlib.Path(sys.argv[1])
rows = "\n".join(" ".join("99.95" if 3 <= r < 7 and 3 <= c < 7 else "100.0" for c in range(10)) for r in range(10))
(t / "s.asc").write_text("ncols 10\nnrows 10\nxllcorner 734000\nyllcorner 4174000\ncellsize 0.1\nNODATA_value -9999\n" + rows + "\n")
PY
gdal_translate -q -a_srs EPSG:32636 -co COMPRESS=DEFLATE "$tmp/s.asc" "$corpus/geotiff/seed_site_crs.tif"
gdal_translate -q -a_srs EPSG:32635 "$tmp/s.asc" "$corpus/geotiff/seed_next_zone.tif"
gdal_translate -q "$tmp/s.asc" "$corpus/geotiff/seed_no_crs.tif"
gdal_translate -q -a_srs EPSG:32636 -a_nodata 100 -ot Float64 "$tmp/s.asc" "$corpus/geotiff/seed_nodata_float64.tif"
printf '%s' '<VRTDataset rasterXSize="1000000" rasterYSize="1000000"><SRS>EPSG:32636</SRS><GeoTransform>734000, 0.01, 0, 4174020, 0, -0.01</GeoTransform><VRTRasterBand dataType="Float32" band="1"></VRTRasterBand></VRTDataset>' > "$corpus/geotiff/seed_huge_header.vrt"
printf '0.1 0.5 0.9 0.5\n' > "$corpus/section_options/seed_across.txt"
printf '0.1,0.5,0.9,0.5 0.001 50 0.5\n' > "$corpus/section_options/seed_fine_step.txt"
printf '734000.2 4174000.5 734000.8 4174000.2 0 20 0.25\n' > "$corpus/section_options/seed_absolute.txt"
printf '0.1 0.5 1e10 0.5 1e-9\n' > "$corpus/section_options/seed_hostile.txt"
printf '0 0.005 0.01 0.003 0.25 0.95\n' > "$corpus/volume_options/seed_defaults.txt"
printf '0.02 0.01 0.02 0.001 0.1 0.99\n' > "$corpus/volume_options/seed_coarse.txt"
printf '0.001 0 0.001 1 10 0.5\n' > "$corpus/volume_options/seed_limits.txt"
printf 'nan 1e308 -1 0x1p-1074 inf 2\n' > "$corpus/volume_options/seed_hostile.txt"
