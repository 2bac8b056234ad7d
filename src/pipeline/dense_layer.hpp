#pragma once
// The dense controller: from a layer's stored alignment to its fused surface
// (level-set .vdb), mesh and dense point cloud under products/<layer>/, recorded
// as products with checksums.
#include "dense/dense.hpp"
#include "pipeline/stage_results.hpp"
#include "project/project.hpp"

#include <string>

namespace strata {

struct DenseLayerResult {
  bool skipped = false;  // inputs unchanged since the last run
  DenseQuality quality;
};

DenseLayerResult dense_layer(Project& project, const std::string& layer, const DenseOptions& options,
                             bool force = false);

// products/<layer>/ relative to the project folder.
std::string layer_product_dir(const std::string& layer);

}  // namespace strata
