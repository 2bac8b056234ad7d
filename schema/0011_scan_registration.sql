-- strata schema 11: scans registered by strata itself (`strata register scan`,
-- docs/range.md, "Registration"). Such a scan becomes 'transform' (its 4x4 into the
-- site frame in `transform`, its box filled in) and these columns say how the pose
-- was found and how well. NULL for scans imported with --crs or --transform.
ALTER TABLE scans ADD COLUMN registered_by TEXT
  CHECK (registered_by IS NULL OR registered_by IN ('icp-layer', 'icp-previous'));
ALTER TABLE scans ADD COLUMN registered_against TEXT;      -- the layer whose surface was the reference
ALTER TABLE scans ADD COLUMN registration_rms_m REAL;      -- RMS point-to-plane residual of the inliers, metres
ALTER TABLE scans ADD COLUMN registration_inliers REAL;    -- share of the thinned scan's points kept as inliers, 0..1
ALTER TABLE scans ADD COLUMN registration_sigma_t_m REAL;  -- pose sigma, translation, metres (largest axis)
ALTER TABLE scans ADD COLUMN registration_sigma_r_rad REAL;  -- pose sigma, rotation, radians (largest axis)
