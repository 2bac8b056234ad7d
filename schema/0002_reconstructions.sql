-- strata schema 2: reconstructions of layers (alignment results and quality),
-- solved cameras, sparse points, marker residuals, camera positions as features.

-- One row per layer and stage run that completed. A rerun replaces the layer's
-- rows for that stage in one transaction.
CREATE TABLE reconstructions (
  id INTEGER PRIMARY KEY,
  layer_id INTEGER NOT NULL REFERENCES layers(id) ON DELETE CASCADE,
  stage TEXT NOT NULL CHECK (stage IN ('sparse', 'dense', 'products')),
  created_at TEXT NOT NULL,
  inputs_key TEXT NOT NULL,          -- SHA-256 of the inputs and options: unchanged -> up to date
  georeferenced INTEGER NOT NULL,
  quality_json TEXT NOT NULL,        -- the figures printed by 'process --json'
  UNIQUE (layer_id, stage)
);

-- Self-calibrated intrinsics per camera (physical camera + focal setting).
CREATE TABLE solved_cameras (
  reconstruction_id INTEGER NOT NULL REFERENCES reconstructions(id) ON DELETE CASCADE,
  camera_id INTEGER NOT NULL REFERENCES cameras(id),
  width INTEGER NOT NULL, height INTEGER NOT NULL,
  fx REAL NOT NULL, fy REAL NOT NULL, cx REAL NOT NULL, cy REAL NOT NULL,  -- pixels
  k1 REAL NOT NULL, k2 REAL NOT NULL,
  PRIMARY KEY (reconstruction_id, camera_id)
);

-- Camera poses: world-to-camera rotation (row-major) and centre in the site
-- frame (metres, site CRS minus the site origin).
CREATE TABLE image_poses (
  reconstruction_id INTEGER NOT NULL REFERENCES reconstructions(id) ON DELETE CASCADE,
  image_id INTEGER NOT NULL REFERENCES images(id) ON DELETE CASCADE,
  registered INTEGER NOT NULL,
  r11 REAL, r12 REAL, r13 REAL, r21 REAL, r22 REAL, r23 REAL, r31 REAL, r32 REAL, r33 REAL,
  cx_site REAL, cy_site REAL, cz_site REAL,
  PRIMARY KEY (reconstruction_id, image_id)
);

-- Sparse points as one blob per reconstruction: n x (3 float64 site frame + 3 uint8
-- colour + float32 error px + uint16 track length), little-endian. Kept compact:
-- a layer has 10^4-10^5 points.
CREATE TABLE sparse_points (
  reconstruction_id INTEGER PRIMARY KEY REFERENCES reconstructions(id) ON DELETE CASCADE,
  count INTEGER NOT NULL,
  data BLOB NOT NULL
);

CREATE TABLE marker_residuals (
  reconstruction_id INTEGER NOT NULL REFERENCES reconstructions(id) ON DELETE CASCADE,
  marker_id INTEGER NOT NULL REFERENCES markers(fid) ON DELETE CASCADE,
  role TEXT NOT NULL CHECK (role IN ('control', 'check', 'rejected')),
  triangulated INTEGER NOT NULL,
  de REAL, dn REAL, dz REAL,         -- metres: photogrammetric minus surveyed
  reprojection_px REAL,
  images INTEGER NOT NULL,
  PRIMARY KEY (reconstruction_id, marker_id)
);

-- Camera positions of every aligned photo: a point feature table for the site plan.
CREATE TABLE camera_positions (
  fid INTEGER PRIMARY KEY AUTOINCREMENT,
  geom POINT,
  layer TEXT NOT NULL,
  image TEXT NOT NULL,
  e REAL NOT NULL, n REAL NOT NULL, z REAL NOT NULL,
  UNIQUE (layer, image)
);
