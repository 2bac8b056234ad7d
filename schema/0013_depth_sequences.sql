-- strata schema 13: RGB-D depth sequences of a layer (`strata import depth`,
-- docs/range.md, "Depth sequences"). A sequence is one pass of a hand-held depth
-- camera: its intrinsics, depth scale and noise, and its frames. Each frame's 16-bit
-- PNG (and its colour frame, when given) is stored like a photo: the original file
-- content-addressed in media/, never modified. `recorded_pose` is the pose the
-- device's own tracking gave (drifting); `pose` is the one `strata register depth`
-- found (NULL until then), with how and how well. Poses are 16 numbers, row-major
-- 4x4, camera (x right, y down, z forward) -> site frame, metres.
CREATE TABLE depth_sequences (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  layer_id INTEGER NOT NULL REFERENCES layers(id),
  name TEXT NOT NULL,                  -- the folder of its frames, or --sequence
  width INTEGER NOT NULL CHECK (width > 0),     -- pixels
  height INTEGER NOT NULL CHECK (height > 0),   -- pixels
  fx REAL NOT NULL CHECK (fx > 0),     -- pixels
  fy REAL NOT NULL CHECK (fy > 0),     -- pixels
  cx REAL NOT NULL,                    -- pixels; (0, 0) is the centre of the top-left pixel
  cy REAL NOT NULL,
  depth_scale_m REAL NOT NULL CHECK (depth_scale_m > 0),  -- metres per unit of the PNG (0.001: millimetres)
  noise_k REAL NOT NULL CHECK (noise_k > 0),              -- 1/m: depth noise, one sigma = noise_k z^2
  intrinsics_file TEXT NOT NULL,       -- the file the intrinsics were read from (name only)
  poses_file TEXT,                     -- the file the recorded poses were read from, if any
  imported_at TEXT NOT NULL,           -- ISO 8601 UTC
  UNIQUE (layer_id, name)
);
CREATE INDEX depth_sequences_layer ON depth_sequences(layer_id);

CREATE TABLE depth_frames (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  sequence_id INTEGER NOT NULL REFERENCES depth_sequences(id),
  frame INTEGER NOT NULL CHECK (frame >= 0),   -- 0-based order in the sequence
  name TEXT NOT NULL,                  -- original file name
  sha256 TEXT NOT NULL UNIQUE,         -- content address in media/
  media_path TEXT NOT NULL,            -- relative to the project folder
  bytes INTEGER NOT NULL,
  valid_pixels INTEGER NOT NULL CHECK (valid_pixels > 0),  -- pixels with a depth (not 0)
  colour_name TEXT,                    -- the colour frame of the same pixels, if given
  colour_sha256 TEXT,
  colour_media_path TEXT,
  recorded_pose TEXT,                  -- the device's pose (--poses), NULL when none was given
  pose TEXT,                           -- the registered pose, NULL until registered
  registered_by TEXT CHECK (registered_by IS NULL OR registered_by IN ('tracking', 'loop-closure')),
  registration_rms_m REAL,             -- RMS point-to-plane residual of the inliers, metres
  registration_inliers REAL,           -- share of the thinned frame's points kept as inliers, 0..1
  registration_sigma_t_m REAL,         -- pose sigma, translation, metres (largest axis; a lower bound)
  registration_sigma_r_rad REAL,       -- pose sigma, rotation, radians (largest axis; a lower bound)
  min_x REAL, min_y REAL, min_z REAL,  -- bounding box of its points, metres, site frame; NULL until registered
  max_x REAL, max_y REAL, max_z REAL,
  UNIQUE (sequence_id, frame),
  UNIQUE (sequence_id, name)
);
CREATE INDEX depth_frames_sequence ON depth_frames(sequence_id);
