#pragma once
// A layer's range scans as inputs of the dense stage (docs/range.md, "Fusion"): the
// registered ones read from media/ into the site frame, chunk by chunk; the
// unregistered ones named, so the controller can say they were left out.
#include "dense/dense.hpp"
#include "project/project.hpp"
#include "project/records.hpp"
#include "project/scan_records.hpp"
#include "project/depth_records.hpp"

#include <optional>
#include <string>
#include <vector>

namespace strata {

struct LayerScans {
  std::vector<RangeScanInput> registered;  // 'survey' and 'transform' scans, then registered depth frames
  std::vector<std::string> unregistered;   // names of the scans no stage can place yet
  int depth_frames = 0;                    // registered depth frames among `registered`
  std::vector<std::string> unregistered_depth;  // depth sequences with frames not registered yet
  std::string key;                         // digest of the registered scans (content, sigma, registration)
  std::optional<ScanBounds> bounds;        // union of the registered scans' boxes, site frame
};

// Each 'transform' scan is fused along its rays from the transform's translation
// (the scanner's origin in the site frame); a 'survey' scan has no station
// (RangeScanInput::station). Its points go through PROJ when its CRS is not the
// site's, then the site origin is subtracted. A registered depth frame is fused like
// a 'transform' scan from its camera centre, each point weighted by its noise k z^2
// (every kDepthFusionStride-th pixel each way), with its pixel's colour when the
// frame has a colour frame.
LayerScans layer_scans(Project& project, const LayerRecord& layer);

}  // namespace strata
