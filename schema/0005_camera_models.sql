-- strata schema 5: the lens model of a solved camera (docs/cameras.md). Until now
-- every camera was 'radial' (k1, k2); Brown adds k3 and the tangential p1, p2, the
-- equidistant fisheye k3 and k4. The defaults keep the rows of earlier versions what
-- they were: radial, higher coefficients zero.
ALTER TABLE solved_cameras ADD COLUMN model TEXT NOT NULL DEFAULT 'radial'
  CHECK (model IN ('radial', 'brown', 'fisheye'));
ALTER TABLE solved_cameras ADD COLUMN k3 REAL NOT NULL DEFAULT 0;  -- brown, fisheye
ALTER TABLE solved_cameras ADD COLUMN k4 REAL NOT NULL DEFAULT 0;  -- fisheye
ALTER TABLE solved_cameras ADD COLUMN p1 REAL NOT NULL DEFAULT 0;  -- brown (tangential)
ALTER TABLE solved_cameras ADD COLUMN p2 REAL NOT NULL DEFAULT 0;  -- brown (tangential)
