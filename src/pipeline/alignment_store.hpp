#pragma once
// Reading and writing a layer's alignment in the project database.
#include "project/project.hpp"
#include "pipeline/stage_results.hpp"
#include "project/records.hpp"
#include "geometry/reconstruction.hpp"

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace strata {

// A layer's alignment as stored: the reconstruction in the site frame, with the
// image and camera rows behind its indices.
struct StoredAlignment {
  std::int64_t reconstruction_id = 0;
  Reconstruction rec;                    // site frame (metres); groups index `camera_ids`
  std::vector<ImageRecord> images;       // same order as rec.images
  std::vector<std::int64_t> camera_ids;  // per group
  AlignmentQuality quality;
  std::string inputs_key;
};

// Replaces the layer's sparse reconstruction (and everything derived from it).
// `marker_ids`: the marker rows by name, for the residuals table.
std::int64_t store_alignment(Database& db, const LayerRecord& layer, const SiteInfo& site,
                             const StoredAlignment& alignment, const std::map<std::string, std::int64_t>& marker_ids);

std::optional<StoredAlignment> load_alignment(Database& db, const LayerRecord& layer);

}  // namespace strata
