-- strata schema 3: products (files derived from the database, with checksums) and
-- unit volumes.

CREATE TABLE products (
  id INTEGER PRIMARY KEY,
  layer_id INTEGER REFERENCES layers(id) ON DELETE CASCADE,  -- NULL for site-wide products
  unit_id INTEGER REFERENCES units(id) ON DELETE CASCADE,    -- for per-unit products
  kind TEXT NOT NULL,        -- surface|mesh|points|dtm|ortho|contours|thickness|voxels|section|report|...
  path TEXT NOT NULL,        -- relative to the project folder
  sha256 TEXT NOT NULL,
  bytes INTEGER NOT NULL,
  params_json TEXT NOT NULL DEFAULT '{}',
  created_at TEXT NOT NULL
);
CREATE UNIQUE INDEX products_path ON products(path);
CREATE INDEX products_layer_kind ON products(layer_id, kind);

CREATE TABLE unit_volumes (
  unit_id INTEGER PRIMARY KEY REFERENCES units(id) ON DELETE CASCADE,
  top_layer TEXT NOT NULL,           -- surface when the unit's top was exposed
  bottom_layers TEXT NOT NULL,       -- surface(s) after it was removed, comma separated
  volume_m3 REAL NOT NULL,
  area_m2 REAL NOT NULL,
  mean_thickness_m REAL NOT NULL,
  min_thickness_m REAL NOT NULL,
  max_thickness_m REAL NOT NULL,
  volume_sigma_m3 REAL,              -- one-sigma uncertainty estimate
  method TEXT NOT NULL,              -- e.g. 'voxels'
  details_json TEXT NOT NULL DEFAULT '{}',
  computed_at TEXT NOT NULL
);
