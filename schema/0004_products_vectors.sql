-- strata schema 4: site-plan vectors derived from the layer products: contour
-- lines and reconstructed footprints per layer (GeoPackage feature tables in the
-- site CRS), and a point view of the markers with their residuals per layer.
-- Rows are replaced per layer when its products are rebuilt.

-- Contour lines of a layer's DTM; z of every vertex = elevation (metres, site CRS).
CREATE TABLE contours (
  fid INTEGER PRIMARY KEY AUTOINCREMENT,
  geom LINESTRING,
  layer TEXT NOT NULL,               -- layer name
  elevation REAL NOT NULL,           -- metres, absolute height
  interval_m REAL NOT NULL,          -- contour interval it belongs to
  length_m REAL NOT NULL,
  min_e REAL NOT NULL, min_n REAL NOT NULL, max_e REAL NOT NULL, max_n REAL NOT NULL
);
CREATE INDEX contours_layer ON contours(layer);

-- Where a layer's surface was reconstructed: outline of the DTM's valid cells.
CREATE TABLE footprints (
  fid INTEGER PRIMARY KEY AUTOINCREMENT,
  geom MULTIPOLYGON,
  layer TEXT NOT NULL UNIQUE,
  area_m2 REAL NOT NULL,
  perimeter_m REAL NOT NULL,
  min_e REAL NOT NULL, min_n REAL NOT NULL, max_e REAL NOT NULL, max_n REAL NOT NULL
);

-- Markers with their residuals in each layer's alignment (photogrammetric minus
-- surveyed, metres): one point per (layer, marker). A view, so it never goes stale;
-- registered as a feature layer by the products stage.
CREATE VIEW marker_residuals_view AS
SELECT mr.rowid AS fid, m.geom AS geom, m.name AS name, l.name AS layer, mr.role AS role,
       mr.triangulated AS triangulated, mr.de AS de_m, mr.dn AS dn_m, mr.dz AS dz_m,
       mr.reprojection_px AS reprojection_px, mr.images AS images
FROM marker_residuals mr
JOIN markers m ON m.fid = mr.marker_id
JOIN reconstructions r ON r.id = mr.reconstruction_id
JOIN layers l ON l.id = r.layer_id;
