#pragma once
// A stored depth frame's points (internal to the pipeline; docs/range.md, "Depth
// sequences"): each pixel with a depth d (in the PNG's units) back-projected through
// the sequence's pinhole intrinsics, z = d x depth_scale_m, x = (u - cx) z / fx,
// y = (v - cy) z / fy, in the camera frame (x right, y down, z forward), metres.
#include "dense/dense.hpp"
#include "project/depth_records.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <vector>

namespace strata {

// Every `stride`-th pixel in each direction (1: all).
std::vector<Eigen::Vector3d> depth_frame_points(const std::filesystem::path& file, const DepthSequenceRecord& sequence,
                                                int stride = 1);

// A registered frame as an input of the fusion, fused like a scan with a station:
// rays from the camera centre, each point's noise k z^2 (z its depth along the
// optical axis), every `stride`-th pixel each way.
RangeScanInput depth_frame_input(const std::filesystem::path& file, const DepthSequenceRecord& sequence,
                                 const DepthFrameRecord& frame, int stride);

}  // namespace strata
