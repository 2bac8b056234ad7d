// importer.calibration: the format detected from the content (OpenCV's YAML or XML,
// Metashape's XML) as `strata camera set --calibration FILE` does, then the
// conversion and validation. An accepted calibration must be usable.
#include "fuzz/fuzz_support.hpp"
#include "fuzz/targets.hpp"
#include "importers/calibration/calibration_importer.hpp"

#include <cmath>

namespace strata::fuzz {

int calibration(const std::uint8_t* data, std::size_t size) {
  constexpr const char* kInputName = "calibration_input.yml";
  const auto file = write_input(kInputName, data, size);
  CalibrationFile c;
  if (!accepts([&] { c = read_calibration_file(file); }, kInputName)) return 0;
  const Intrinsics& k = c.intrinsics;
  if (k.width <= 0 || k.height <= 0 || !(std::isfinite(k.fx) && k.fx > 0) || !(std::isfinite(k.fy) && k.fy > 0)) {
    throw FuzzFailure("an accepted calibration has no positive image size or focal length");
  }
  return 0;
}

}  // namespace strata::fuzz
