#include "importers/photos/exif.hpp"

#include "core/error.hpp"
#include "importers/photos/sensor_database.hpp"

#include <exiv2/exiv2.hpp>

#include <cmath>
#include <limits>

namespace strata {
namespace {

std::optional<double> number(const Exiv2::ExifData& exif, const char* key) {
  auto it = exif.findKey(Exiv2::ExifKey(key));
  if (it == exif.end() || it->count() == 0) return std::nullopt;
  const Exiv2::Rational r = it->toRational(0);
  if (r.second == 0) return std::nullopt;
  const double v = double(r.first) / double(r.second);
  if (!std::isfinite(v) || v <= 0) return std::nullopt;
  return v;
}

// A count (pixels, a unit code) as int; none when it is not one (EXIF rationals reach 2^31).
std::optional<int> whole(std::optional<double> v) {
  if (!v || *v > std::numeric_limits<int>::max()) return std::nullopt;
  return int(*v);
}

std::string text(const Exiv2::ExifData& exif, const char* key) {
  auto it = exif.findKey(Exiv2::ExifKey(key));
  if (it == exif.end()) return {};
  std::string s = it->toString();
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
  return s;
}

}  // namespace

PhotoMetadata read_photo_metadata(const std::filesystem::path& path) {
  PhotoMetadata m;
  try {
    auto image = Exiv2::ImageFactory::open(path.string());
    image->readMetadata();
    m.width = image->pixelWidth();
    m.height = image->pixelHeight();
    const Exiv2::ExifData& exif = image->exifData();
    if (exif.empty()) return m;
    m.has_exif = true;
    m.make = text(exif, "Exif.Image.Make");
    m.model = text(exif, "Exif.Image.Model");
    m.focal_mm = number(exif, "Exif.Photo.FocalLength");
    m.focal_35mm = number(exif, "Exif.Photo.FocalLengthIn35mmFilm");
    m.exif_width = whole(number(exif, "Exif.Photo.PixelXDimension"));
    m.exif_height = whole(number(exif, "Exif.Photo.PixelYDimension"));
    m.focal_plane_x_res = number(exif, "Exif.Photo.FocalPlaneXResolution");
    if (auto unit = whole(number(exif, "Exif.Photo.FocalPlaneResolutionUnit"))) {
      // EXIF: 2 = inch, 3 = centimetre, 4 = millimetre, 5 = micrometre.
      const int u = *unit;
      if (u == 2) m.focal_plane_unit_mm = 25.4;
      if (u == 3) m.focal_plane_unit_mm = 10.0;
      if (u == 4) m.focal_plane_unit_mm = 1.0;
      if (u == 5) m.focal_plane_unit_mm = 0.001;
    }
    std::string dt = text(exif, "Exif.Photo.DateTimeOriginal");
    if (dt.empty()) dt = text(exif, "Exif.Image.DateTime");
    // "YYYY:MM:DD HH:MM:SS" -> "YYYY-MM-DDTHH:MM:SS"
    if (dt.size() >= 19 && dt[4] == ':' && dt[7] == ':') {
      dt[4] = '-';
      dt[7] = '-';
      dt[10] = 'T';
      m.captured_at = dt.substr(0, 19);
    }
  } catch (const Exiv2::Error& e) {
    throw InputError(fmt::format("{}: cannot read image metadata: {}", path.string(), e.what()));
  }
  return m;
}

FocalPrior focal_prior(const PhotoMetadata& m) {
  FocalPrior p;
  const int long_side = std::max(m.width, m.height);
  if (long_side <= 0) return p;
  if (m.focal_mm) {
    if (auto sw = lookup_sensor_width_mm(m.make, m.model)) {
      p.sensor_width_mm = *sw;
      p.focal_px = *m.focal_mm / *sw * long_side;
      p.source = "sensor_list";
      return p;
    }
    if (m.focal_plane_x_res && m.focal_plane_unit_mm && m.exif_width) {
      // The focal-plane resolution refers to the camera's own image size, which
      // may differ from this file's (resized copies keep the original EXIF).
      const int exif_long = std::max(*m.exif_width, m.exif_height.value_or(0));
      const double sw = exif_long / *m.focal_plane_x_res * *m.focal_plane_unit_mm;
      if (sw > 1.0 && sw < 100.0) {
        p.sensor_width_mm = sw;
        p.focal_px = *m.focal_mm / sw * long_side;
        p.source = "focal_plane";
        return p;
      }
    }
  }
  if (m.focal_35mm) {
    const double diagonal_px = std::hypot(double(m.width), double(m.height));
    p.focal_px = *m.focal_35mm / 43.2666 * diagonal_px;
    p.source = "35mm";
  }
  return p;
}

}  // namespace strata
