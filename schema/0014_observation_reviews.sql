-- strata schema 14: a person's review of where strata saw a marker in a photo (the
-- field station's marker workspace, docs/field_station.md). strata makes two kinds of
-- observation itself: 'guided' (predicted from the clicks by `markers guide`) and
-- 'detected' (a coded target). A person confirms one (a guided position becomes a
-- click there; a detection is kept as it is) or rejects it: a rejected observation is
-- not used by the georeference, and neither the guide nor the detection makes it
-- again. One review per marker and photo; withdrawing it deletes the row.
CREATE TABLE observation_reviews (
  id INTEGER PRIMARY KEY,
  marker_id INTEGER NOT NULL REFERENCES markers(fid) ON DELETE CASCADE,
  image_id INTEGER NOT NULL REFERENCES images(id) ON DELETE CASCADE,
  verdict TEXT NOT NULL CHECK (verdict IN ('confirmed', 'rejected')),
  source TEXT NOT NULL CHECK (source IN ('detected', 'guided')),  -- what was reviewed
  x REAL NOT NULL,                   -- pixels, where it was (0,0) = centre of the top-left pixel
  y REAL NOT NULL,
  reviewed_at TEXT NOT NULL,         -- ISO 8601 UTC
  UNIQUE (marker_id, image_id)
);
CREATE INDEX observation_reviews_image ON observation_reviews(image_id);
