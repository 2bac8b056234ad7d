-- strata schema 9: finds recorded in place (a total station's point per object), a
-- GeoPackage point feature table (3D) in the site CRS. `unit` is the unit the
-- excavator recorded the find in; `strata finds` compares it with the unit whose
-- solid holds the point. Re-importing an id replaces its row only with --update.
CREATE TABLE finds (
  fid INTEGER PRIMARY KEY AUTOINCREMENT,
  geom POINT,
  find_id TEXT NOT NULL UNIQUE,      -- the find's number as written on its bag
  unit TEXT NOT NULL REFERENCES units(code),  -- recorded unit code
  type TEXT NOT NULL DEFAULT '',     -- e.g. pottery, bone, lithic, metal
  description TEXT NOT NULL DEFAULT '',
  e REAL NOT NULL,                   -- metres, site CRS
  n REAL NOT NULL,
  z REAL NOT NULL,
  source TEXT NOT NULL DEFAULT '',   -- file it came from, or 'find add'
  imported_at TEXT NOT NULL          -- ISO 8601 UTC
);
CREATE INDEX finds_unit ON finds(unit);
