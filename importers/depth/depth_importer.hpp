#pragma once
// importer.depth: an RGB-D depth sequence of one layer (docs/range.md, "Depth
// sequences"): 16-bit PNG depth frames in the order given, the camera's
// intrinsics, optional colour frames and the poses the device recorded. Every file
// is read through and checked first; then the frames are copied unchanged into the
// media store and recorded (tables depth_sequences, depth_frames). All or nothing:
// one bad file and nothing is imported.
#include "importers/depth/depth_files.hpp"
#include "project/project.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace strata {

// Structured-light and active-stereo depth cameras at 0.5-4 m: one sigma of about
// 1.5 mm at 1 m, growing with the square of the depth (Khoshelham & Elberink 2012
// measured 1.5 mm at 1 m to 4 cm at 5 m for the Kinect; k = sigma / z^2).
constexpr double kDefaultDepthNoiseK = 0.0015;  // 1/m

struct DepthImportOptions {
  std::string layer;                                 // required: the layer the sequence records
  std::filesystem::path intrinsics;                  // required: the camera's intrinsics file
  double depth_scale_m = 0.001;                      // metres per unit of the PNG (millimetres); > 0
  double noise_k = kDefaultDepthNoiseK;              // 1/m: depth noise sigma = noise_k z^2; > 0
  std::optional<std::filesystem::path> poses;        // the device's recorded poses, one per frame
  std::optional<std::filesystem::path> colour_dir;   // colour frames, the same file names as the depth frames
  std::optional<std::string> sequence;               // its name; default: the folder of the first frame
  void validate() const;                             // throws InputError naming the option
};

struct DepthImportSummary {
  std::string sequence;
  int frames = 0;
  int with_colour = 0;
  int with_pose = 0;
  std::int64_t valid_pixels = 0;
  DepthIntrinsics intrinsics;
};

DepthImportSummary import_depth(Project& project, const DepthImportOptions& options,
                                const std::vector<std::filesystem::path>& frames);

}  // namespace strata
