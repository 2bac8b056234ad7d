-- strata schema 12: scans registered on surveyed targets (`strata register scan
-- --targets`, docs/range.md, "On surveyed targets"): registered_by may now be
-- 'targets', and registered_against then names the target file. SQLite cannot change
-- a column's CHECK in place, so the table is rebuilt with the same columns, in the
-- same order, and its rows copied as they are.
CREATE TABLE scans_12 (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  layer_id INTEGER NOT NULL REFERENCES layers(id),
  name TEXT NOT NULL,
  sha256 TEXT NOT NULL UNIQUE,
  media_path TEXT NOT NULL,
  bytes INTEGER NOT NULL,
  format TEXT NOT NULL,
  points INTEGER NOT NULL CHECK (points > 0),
  has_colour INTEGER NOT NULL,
  has_intensity INTEGER NOT NULL,
  has_normals INTEGER NOT NULL,
  sigma_m REAL NOT NULL CHECK (sigma_m > 0),
  registration TEXT NOT NULL CHECK (registration IN ('survey', 'transform', 'unregistered')),
  crs TEXT,
  transform TEXT,
  min_x REAL, min_y REAL, min_z REAL,
  max_x REAL, max_y REAL, max_z REAL,
  imported_at TEXT NOT NULL,
  registered_by TEXT CHECK (registered_by IS NULL OR registered_by IN ('icp-layer', 'icp-previous', 'targets')),
  registered_against TEXT,       -- the layer whose surface was the reference, or the target file's name
  registration_rms_m REAL,       -- RMS residual of the inliers (points to the surface, or targets), metres
  registration_inliers REAL,     -- share of the thinned scan's points, or of the targets, kept as inliers, 0..1
  registration_sigma_t_m REAL,
  registration_sigma_r_rad REAL,
  UNIQUE (layer_id, name)
);
INSERT INTO scans_12 SELECT * FROM scans;
DROP TABLE scans;
ALTER TABLE scans_12 RENAME TO scans;
CREATE INDEX scans_layer ON scans(layer_id);
