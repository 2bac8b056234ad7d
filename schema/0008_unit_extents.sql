-- strata schema 8: the excavated extent of each unit, as `strata volume` found it
-- (where its top and bottom surfaces differ significantly, or its footprint, or
-- within the trench outline), and the interval of its volume. A GeoPackage
-- feature table in the site CRS; rows are replaced with unit_volumes.
CREATE TABLE unit_extents (
  fid INTEGER PRIMARY KEY AUTOINCREMENT,
  geom MULTIPOLYGON,
  unit TEXT NOT NULL UNIQUE,         -- unit code
  method TEXT NOT NULL,              -- 'significance', 'significance within the outline', 'footprint'
  area_m2 REAL NOT NULL,             -- area of the dug cells (the polygons follow their edges)
  volume_m3 REAL NOT NULL,
  volume_low_m3 REAL NOT NULL,       -- interval at `confidence`
  volume_high_m3 REAL NOT NULL,
  confidence REAL NOT NULL,
  min_e REAL NOT NULL, min_n REAL NOT NULL, max_e REAL NOT NULL, max_n REAL NOT NULL
);
