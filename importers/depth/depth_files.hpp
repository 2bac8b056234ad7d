#pragma once
// The files of an RGB-D depth sequence (docs/range.md, "Depth sequences"): the
// 16-bit PNG depth frames, their colour frames, the camera's intrinsics and the
// poses the device recorded. Every reader checks the whole file and refuses it with
// one message naming its stage, the file and the line or byte at fault.
#include "project/depth_records.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace strata {

// What a PNG's header says (its IHDR chunk), after every chunk's length and CRC was
// checked and the IEND chunk found.
struct PngHeader {
  int width = 0, height = 0;  // pixels
  int bit_depth = 0;          // bits per channel
  int colour_type = 0;        // 0 grey, 2 RGB, 3 palette, 4 grey + alpha, 6 RGBA
};

// importer.depth.png: walks the chunks of a PNG (signature, IHDR first, each
// chunk's length inside the file and its CRC-32, IEND last). `stage` starts the
// messages.
PngHeader check_png(const std::filesystem::path& file, const char* stage);

// A depth frame decoded: one 16-bit unsigned value a pixel, row-major, 0 = no depth.
struct DepthImage {
  int width = 0, height = 0;
  std::vector<std::uint16_t> values;
  std::int64_t valid = 0;  // pixels with a depth
};

// importer.depth.png: a 16-bit greyscale PNG of the intrinsics' size, checked
// (check_png) and decoded; refused when it holds no depth at all.
DepthImage read_depth_png(const std::filesystem::path& file, const DepthIntrinsics& intrinsics);

// importer.depth.colour: an 8-bit grey, RGB or RGBA PNG of the intrinsics' size
// (the same pixels as its depth frame), checked and decoded once.
void check_colour_png(const std::filesystem::path& file, const DepthIntrinsics& intrinsics);

// importer.depth.intrinsics: 'key value' lines (whitespace or comma separated, '#'
// comments), keys width, height (pixels, whole numbers), fx, fy, cx, cy (pixels;
// (0, 0) the centre of the top-left pixel). Each exactly once.
DepthIntrinsics read_depth_intrinsics(const std::filesystem::path& file);

// importer.depth.poses: one line a frame, 'file tx ty tz qx qy qz qw' (the TUM RGB-D
// trajectory layout with the depth file's name in place of the time stamp): camera
// (x right, y down, z forward) -> site frame, metres; the quaternion of unit norm
// to 1e-3 (it is then normalised). A name given twice is refused.
std::vector<std::pair<std::string, Eigen::Isometry3d>> read_depth_poses(const std::filesystem::path& file);

}  // namespace strata
