-- strata schema 1: GeoPackage core tables, site, stratigraphy, layers, photos,
-- cameras, markers and their image observations.
-- Applied in one transaction; strata_meta.schema_version records the level.
-- (PRAGMA user_version belongs to GeoPackage: it must read 10200, see docs/schema.md.)

-- ---- GeoPackage 1.2 core (OGC 12-128r15, clauses 1.1.2, 1.1.3, 2.1.5) -------------
CREATE TABLE gpkg_spatial_ref_sys (
  srs_name TEXT NOT NULL,
  srs_id INTEGER NOT NULL PRIMARY KEY,
  organization TEXT NOT NULL,
  organization_coordsys_id INTEGER NOT NULL,
  definition TEXT NOT NULL,
  description TEXT
);
INSERT INTO gpkg_spatial_ref_sys VALUES
  ('Undefined cartesian SRS', -1, 'NONE', -1, 'undefined', 'undefined cartesian coordinate reference system'),
  ('Undefined geographic SRS', 0, 'NONE', 0, 'undefined', 'undefined geographic coordinate reference system'),
  ('WGS 84 geodetic', 4326, 'EPSG', 4326,
   'GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],AXIS["Latitude",NORTH],AXIS["Longitude",EAST],AUTHORITY["EPSG","4326"]]',
   'longitude/latitude coordinates in decimal degrees on the WGS 84 spheroid');

CREATE TABLE gpkg_contents (
  table_name TEXT NOT NULL PRIMARY KEY,
  data_type TEXT NOT NULL,
  identifier TEXT UNIQUE,
  description TEXT DEFAULT '',
  last_change DATETIME NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')),
  min_x DOUBLE, min_y DOUBLE, max_x DOUBLE, max_y DOUBLE,
  srs_id INTEGER,
  CONSTRAINT fk_gc_r_srs_id FOREIGN KEY (srs_id) REFERENCES gpkg_spatial_ref_sys(srs_id)
);

CREATE TABLE gpkg_geometry_columns (
  table_name TEXT NOT NULL,
  column_name TEXT NOT NULL,
  geometry_type_name TEXT NOT NULL,
  srs_id INTEGER NOT NULL,
  z TINYINT NOT NULL,
  m TINYINT NOT NULL,
  CONSTRAINT pk_geom_cols PRIMARY KEY (table_name, column_name),
  CONSTRAINT uk_gc_table_name UNIQUE (table_name),
  CONSTRAINT fk_gc_tn FOREIGN KEY (table_name) REFERENCES gpkg_contents(table_name),
  CONSTRAINT fk_gc_srs FOREIGN KEY (srs_id) REFERENCES gpkg_spatial_ref_sys (srs_id)
);

-- ---- strata ------------------------------------------------------------------------
CREATE TABLE strata_meta (
  key TEXT PRIMARY KEY,
  value TEXT NOT NULL
);

-- One row: the site. Its CRS is projected in metres; the origin (metres, site CRS)
-- defines the local site frame used for all geometry in double precision.
CREATE TABLE site (
  id INTEGER PRIMARY KEY CHECK (id = 1),
  name TEXT NOT NULL,
  crs TEXT NOT NULL,                 -- e.g. EPSG:32636
  srs_id INTEGER NOT NULL REFERENCES gpkg_spatial_ref_sys(srs_id),
  origin_e REAL NOT NULL,
  origin_n REAL NOT NULL,
  origin_z REAL NOT NULL,
  origin_set INTEGER NOT NULL DEFAULT 0,  -- 1 once fixed from the first surveyed markers
  created_at TEXT NOT NULL
);

CREATE TABLE units (
  id INTEGER PRIMARY KEY,
  code TEXT NOT NULL UNIQUE,
  type TEXT NOT NULL CHECK (type IN ('deposit', 'cut', 'structure', 'interface')),
  description TEXT NOT NULL DEFAULT ''
);

-- Stored in canonical direction only (inverses such as below/cut_by/filled_by are
-- turned around on input). above/cuts/fills are temporal (Harris matrix edges from
-- the later unit a to the earlier unit b); same_as and contemporary_with are
-- symmetric; abuts is physical, and temporal in the same sense as above.
CREATE TABLE relations (
  id INTEGER PRIMARY KEY,
  unit_a INTEGER NOT NULL REFERENCES units(id) ON DELETE CASCADE,
  kind TEXT NOT NULL CHECK (kind IN ('above', 'cuts', 'fills', 'abuts', 'same_as', 'contemporary_with')),
  unit_b INTEGER NOT NULL REFERENCES units(id) ON DELETE CASCADE,
  CHECK (unit_a <> unit_b),
  UNIQUE (unit_a, kind, unit_b)
);

CREATE TABLE layers (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  unit_id INTEGER NOT NULL REFERENCES units(id),
  captured_at TEXT                   -- ISO 8601, optional
);

-- A physical camera at one focal setting and image size: photos of one camera
-- share their self-calibrated intrinsics.
CREATE TABLE cameras (
  id INTEGER PRIMARY KEY,
  make TEXT NOT NULL DEFAULT '',
  model TEXT NOT NULL DEFAULT '',
  width INTEGER NOT NULL,            -- pixels
  height INTEGER NOT NULL,           -- pixels
  focal_mm REAL,                     -- EXIF FocalLength
  focal_35mm REAL,                   -- EXIF FocalLengthIn35mmFilm
  sensor_width_mm REAL,              -- from the shipped list or EXIF focal-plane resolution
  focal_px REAL,                     -- prior focal length in pixels, NULL when unknown
  focal_source TEXT NOT NULL DEFAULT 'unknown',  -- sensor_list|focal_plane|35mm|unknown
  UNIQUE (make, model, width, height, focal_mm)
);

CREATE TABLE images (
  id INTEGER PRIMARY KEY,
  layer_id INTEGER NOT NULL REFERENCES layers(id),
  name TEXT NOT NULL,                -- original file name
  sha256 TEXT NOT NULL UNIQUE,       -- content address in media/
  media_path TEXT NOT NULL,          -- relative to the project folder
  bytes INTEGER NOT NULL,
  width INTEGER NOT NULL,
  height INTEGER NOT NULL,
  camera_id INTEGER REFERENCES cameras(id),
  captured_at TEXT,                  -- EXIF DateTimeOriginal as ISO 8601
  exif_ok INTEGER NOT NULL DEFAULT 0,
  imported_at TEXT NOT NULL,
  UNIQUE (layer_id, name)
);

-- Surveyed markers (ground control), a GeoPackage point feature table in the site CRS.
CREATE TABLE markers (
  fid INTEGER PRIMARY KEY AUTOINCREMENT,
  geom POINT,
  name TEXT NOT NULL UNIQUE,
  e REAL NOT NULL,                   -- metres, site CRS
  n REAL NOT NULL,
  z REAL NOT NULL,
  sigma_e REAL NOT NULL,             -- metres, 1 sigma
  sigma_n REAL NOT NULL,
  sigma_z REAL NOT NULL,
  kind TEXT NOT NULL DEFAULT 'control' CHECK (kind IN ('control', 'check')),
  source TEXT NOT NULL DEFAULT ''    -- file it came from
);

CREATE TABLE observations (
  id INTEGER PRIMARY KEY,
  marker_id INTEGER NOT NULL REFERENCES markers(fid) ON DELETE CASCADE,
  image_id INTEGER NOT NULL REFERENCES images(id) ON DELETE CASCADE,
  x REAL NOT NULL,                   -- pixels, original photo, (0,0) = centre of top-left pixel
  y REAL NOT NULL,
  source TEXT NOT NULL CHECK (source IN ('detected', 'manual')),
  UNIQUE (marker_id, image_id, source)
);
CREATE INDEX observations_image ON observations(image_id);
