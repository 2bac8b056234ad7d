-- strata schema 10: range scans (terrestrial laser scanner, phone LiDAR point clouds)
-- of a layer, stored like photos: the original file content-addressed in media/,
-- never modified, one row per scan. `registration` says how the scan's frame relates
-- to the site: 'survey' (already in a CRS, `crs`), 'transform' (a 4x4 similarity into
-- the site frame, `transform`), 'unregistered' (its own frame; a later stage registers
-- it). The bounding box is in the site frame (CRS minus the site origin) and NULL
-- while unregistered.
CREATE TABLE scans (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  layer_id INTEGER NOT NULL REFERENCES layers(id),
  name TEXT NOT NULL,                -- original file name
  sha256 TEXT NOT NULL UNIQUE,       -- content address in media/
  media_path TEXT NOT NULL,          -- relative to the project folder
  bytes INTEGER NOT NULL,
  format TEXT NOT NULL,              -- e.g. 'ply binary_little_endian', 'las 1.4 point format 6', 'pts', 'xyz'
  points INTEGER NOT NULL CHECK (points > 0),
  has_colour INTEGER NOT NULL,
  has_intensity INTEGER NOT NULL,
  has_normals INTEGER NOT NULL,
  sigma_m REAL NOT NULL CHECK (sigma_m > 0),  -- instrument range noise, one sigma, metres
  registration TEXT NOT NULL CHECK (registration IN ('survey', 'transform', 'unregistered')),
  crs TEXT,                          -- 'survey': the CRS of the file's coordinates, e.g. 'EPSG:32636'
  transform TEXT,                    -- 'transform': 16 numbers, row-major 4x4, scanner frame -> site frame
  min_x REAL, min_y REAL, min_z REAL,  -- bounding box, metres, site frame; NULL when unregistered
  max_x REAL, max_y REAL, max_z REAL,
  imported_at TEXT NOT NULL,         -- ISO 8601 UTC
  UNIQUE (layer_id, name)
);
CREATE INDEX scans_layer ON scans(layer_id);
