#pragma once
// The products controller: from a layer's fused surface and stored
// alignment to its DTM and true orthophoto (COG GeoTIFFs under products/<layer>/),
// contour lines and footprint (project.gpkg feature tables), recorded as products
// in one transaction, then the raster tables dtm_<layer> / ortho_<layer> written
// into project.gpkg through GDAL. No maths here: that is in src/products/.
#include "products/dtm.hpp"
#include "products/ortho_markers.hpp"
#include "products/orthophoto.hpp"
#include "exporters/raster/geotiff.hpp"
#include "products/site_plan.hpp"
#include "pipeline/stage_results.hpp"
#include "project/project.hpp"

#include <string>

namespace strata {

struct ProductsOptions {
  DtmOptions dtm;                  // cell 5 mm by default
  double ortho_cell_m = 0;         // metres; 0 = the DTM cell
  OrthoOptions ortho;
  // Coded targets found in the orthophoto against the surveyed markers.
  // The target dictionary and naming should be those the photos were processed with.
  bool check_ortho_markers = true;
  OrthoMarkerCheckOptions ortho_markers;
  ContourOptions contours;         // interval 5 cm by default
  double min_footprint_area_m2 = 0.01;  // islands of the footprint smaller than this are dropped
  GeoTiffOptions geotiff;          // COG + DEFLATE by default
  bool gpkg_rasters = true;        // also store dtm_/ortho_<layer> raster tables in project.gpkg
  // Throws InputError naming the first invalid field.
  void validate() const;
};

struct ProductsLayerResult {
  bool skipped = false;            // inputs unchanged since the last run
  ProductsQuality quality;
};

ProductsLayerResult products_layer(Project& project, const std::string& layer, const ProductsOptions& options,
                                   bool force = false);

// The views of a layer's stored alignment (registered photos with their cameras).
std::vector<OrthoView> layer_ortho_views(Project& project, const std::string& layer);
// The layer's fused surface (.vdb), or ProcessingError telling how to make it.
std::filesystem::path layer_surface_path(Project& project, const std::string& layer);

}  // namespace strata
