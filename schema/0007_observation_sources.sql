-- strata schema 7: where a marker observation came from.
--   detected  a coded target found by strata (ArUco)
--   clicked   placed by a person: typed, or imported from a gcp_list / CSV
--             (schema 1 called this 'manual'; those rows become 'clicked')
--   guided    found by 'strata markers guide': predicted from the clicks of the same
--             marker and refined to sub-pixel in the photo
-- SQLite cannot change a CHECK constraint in place, so the table is rebuilt (the
-- procedure of https://www.sqlite.org/lang_altertable.html, section 7), keeping every
-- id. No table, view or trigger refers to observations, and observations is not a
-- GeoPackage contents table, so nothing else needs to follow the rename.
CREATE TABLE observations_v7 (
  id INTEGER PRIMARY KEY,
  marker_id INTEGER NOT NULL REFERENCES markers(fid) ON DELETE CASCADE,
  image_id INTEGER NOT NULL REFERENCES images(id) ON DELETE CASCADE,
  x REAL NOT NULL,                   -- pixels, original photo, (0,0) = centre of top-left pixel
  y REAL NOT NULL,
  source TEXT NOT NULL CHECK (source IN ('detected', 'clicked', 'guided')),
  UNIQUE (marker_id, image_id, source)
);
INSERT INTO observations_v7(id, marker_id, image_id, x, y, source)
  SELECT id, marker_id, image_id, x, y, CASE source WHEN 'manual' THEN 'clicked' ELSE source END
  FROM observations;
DROP TABLE observations;
ALTER TABLE observations_v7 RENAME TO observations;
CREATE INDEX observations_image ON observations(image_id);
