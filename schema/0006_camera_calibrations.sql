-- strata schema 6: known calibrations of cameras ('strata camera set', an imported
-- OpenCV or Metashape calibration file, or another layer's solved intrinsics).
-- At most one per camera; the alignment starts that camera's intrinsics from it and,
-- when `fixed`, holds them constant in every adjustment. Replaced or removed by
-- 'camera set' / 'import calibration' / 'camera clear', one transaction per command.

-- Values are in the camera's own image size (cameras.width x cameras.height) and in
-- strata's conventions (docs/cameras.md): pixels with (0,0) at the centre of the
-- top-left pixel, OpenCV's order of the tangential terms.
CREATE TABLE camera_calibrations (
  camera_id INTEGER PRIMARY KEY REFERENCES cameras(id) ON DELETE CASCADE,
  model TEXT NOT NULL CHECK (model IN ('radial', 'brown', 'fisheye')),
  fx REAL NOT NULL, fy REAL NOT NULL,     -- pixels
  cx REAL NOT NULL, cy REAL NOT NULL,     -- pixels
  k1 REAL NOT NULL DEFAULT 0, k2 REAL NOT NULL DEFAULT 0,  -- unitless, per model
  k3 REAL NOT NULL DEFAULT 0, k4 REAL NOT NULL DEFAULT 0,
  p1 REAL NOT NULL DEFAULT 0, p2 REAL NOT NULL DEFAULT 0,
  fixed INTEGER NOT NULL CHECK (fixed IN (0, 1)),  -- 1: held constant, 0: a starting value
  source TEXT NOT NULL,                   -- "camera set", "file cal.yml (opencv)", "layer L7"
  set_at TEXT NOT NULL                    -- ISO 8601 UTC
);
