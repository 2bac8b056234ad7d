#pragma once
// A stored depth frame's points (internal to the pipeline; docs/range.md, "Depth
// sequences"): each pixel with a depth d (in the PNG's units) back-projected through
// the sequence's pinhole intrinsics, z = d x depth_scale_m, x = (u - cx) z / fx,
// y = (v - cy) z / fy, in the camera frame (x right, y down, z forward), metres.
#include "dense/dense.hpp"
#include "project/depth_records.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

namespace strata {

// Every `stride`-th pixel in each direction (1: all). With `pixels`, the index of
// each point's pixel (row-major, v x width + u) there.
std::vector<Eigen::Vector3d> depth_frame_points(const std::filesystem::path& file, const DepthSequenceRecord& sequence,
                                                int stride = 1, std::vector<std::size_t>* pixels = nullptr);

// A frame's colour frame decoded: 3 bytes a pixel (sRGB, R G B), row-major; grey
// frames repeated in the three, RGBA's alpha dropped. Throws IoError naming the
// file when it cannot be decoded or is not the intrinsics' size.
std::vector<std::uint8_t> depth_colour_frame(const std::filesystem::path& file, const DepthIntrinsics& intrinsics);

// A registered frame as an input of the fusion, fused like a scan with a station:
// rays from the camera centre, each point's noise k z^2 (z its depth along the
// optical axis), every `stride`-th pixel each way. With `colour` (the frame's colour
// frame in media/), each point carries its pixel's colour; without, none.
RangeScanInput depth_frame_input(const std::filesystem::path& file, const DepthSequenceRecord& sequence,
                                 const DepthFrameRecord& frame, int stride,
                                 const std::optional<std::filesystem::path>& colour = std::nullopt);

}  // namespace strata
