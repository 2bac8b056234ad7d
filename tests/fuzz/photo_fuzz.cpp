// importer.photos on one photo: the full validation (format sniffing, end marker,
// decoding), then the EXIF that the importer reads and the focal-length prior
// derived from it. The input is written as .jpg; the importer goes by content.
#include "fuzz/fuzz_support.hpp"
#include "fuzz/targets.hpp"
#include "importers/photos/exif.hpp"
#include "importers/photos/photo_importer.hpp"

#include <cmath>

namespace strata::fuzz {

int photo(const std::uint8_t* data, std::size_t size) {
  constexpr const char* kInputName = "photo_input.jpg";
  const auto file = write_input(kInputName, data, size);
  // The importer reads the metadata only of a file that passed the check.
  if (!check_image_file(file).empty()) return 0;
  PhotoMetadata meta;
  if (!accepts([&] { meta = read_photo_metadata(file); }, kInputName)) return 0;
  const FocalPrior prior = focal_prior(meta);
  if (prior.focal_px && !(std::isfinite(*prior.focal_px) && *prior.focal_px > 0)) {
    throw FuzzFailure("focal_prior gave a focal length that is not a positive number");
  }
  return 0;
}

}  // namespace strata::fuzz
