// importer.calibration.metashape: a camera calibration exported by Agisoft Metashape
// (Tools > Camera Calibration > Export, "Agisoft Camera Calibration (*.xml)"):
//   <calibration><projection>frame|fisheye</projection><width/><height/><f/><cx/><cy/>
//   <b1/><b2/><k1/>..<k4/><p1/><p2/>[<p3/><p4/>]</calibration>
// and the <calibration type="frame"><resolution width= height=/>...</calibration>
// element of a Metashape cameras.xml export.
//
// Metashape's frame camera (Metashape Professional manual, appendix "Camera models"):
//   x' = x (1 + K1 r^2 + K2 r^4 + K3 r^6 + K4 r^8) + P1 (r^2 + 2 x^2) + 2 P2 x y
//   y' = y (1 + ...)                               + P2 (r^2 + 2 y^2) + 2 P1 x y
//   u = w/2 + cx + x' (f + B1) + y' B2,   v = h/2 + cy + y' f
// with u, v measured from the top-left corner of the image. Against OpenCV's (and
// strata's) Brown model this means:
//   - the tangential terms are named the other way round: p1 = P2, p2 = P1;
//   - cx, cy are offsets from the image centre, in corner-origin pixels: strata's
//     principal point (origin at the centre of the top-left pixel) is w/2 + cx - 0.5;
//   - B1 (affinity) is a difference of focal lengths: fx = f + B1, fy = f;
//   - B2 (skew) and K4 (r^8) have no counterpart: refused unless negligible (B2) or 0.
// The fisheye camera applies the same polynomial to theta = atan(r) (equidistant,
// Kannala-Brandt as OpenCV's cv::fisheye) and is strata's fisheye model with K1..K4;
// its tangential terms have no counterpart.
#include "importers/calibration/calibration_formats.hpp"

#include "core/error.hpp"

#include <cpl_error.h>
#include <cpl_minixml.h>
#include <fmt/format.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>

namespace fs = std::filesystem;

namespace strata::calibration_formats {
namespace {

// Skew B2 moves a point by B2 * y' pixels; up to this much at the image's top and
// bottom edge it is dropped (with a note), beyond it the file is refused.
constexpr double kMaxDroppedSkewPx = 0.1;

std::string where(const fs::path& file) { return fmt::format("{}: {}", kMetashapeStage, file.string()); }

struct XmlDeleter {
  void operator()(CPLXMLNode* n) const { CPLDestroyXMLNode(n); }
};
using XmlTree = std::unique_ptr<CPLXMLNode, XmlDeleter>;

XmlTree parse_xml(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot be read", where(file)));
  std::stringstream ss;
  ss << in.rdbuf();
  CPLPushErrorHandler(CPLQuietErrorHandler);
  CPLErrorReset();
  XmlTree tree(CPLParseXMLString(ss.str().c_str()));
  const std::string message = CPLGetLastErrorMsg();
  CPLPopErrorHandler();
  if (!tree) {
    // GDAL's parser names the line and column, e.g. "Parse error at line 3, unexpected ...".
    throw InputError(fmt::format("{}: not a valid XML file: {}", where(file),
                                 message.empty() ? "empty document" : message));
  }
  return tree;
}

void collect_calibrations(CPLXMLNode* node, std::vector<CPLXMLNode*>& out) {
  for (; node; node = node->psNext) {
    if (node->eType != CXT_Element) continue;
    if (std::string(node->pszValue) == "calibration") {
      out.push_back(node);
      continue;
    }
    collect_calibrations(node->psChild, out);
  }
}

// The one <calibration> of the file; of a cameras.xml with initial and adjusted
// calibrations of one sensor, the adjusted one.
CPLXMLNode* find_calibration(CPLXMLNode* root, const fs::path& file) {
  std::vector<CPLXMLNode*> all;
  collect_calibrations(root, all);
  if (all.empty()) throw InputError(fmt::format("{}: no <calibration> element", where(file)));
  if (all.size() == 1) return all.front();
  std::vector<CPLXMLNode*> adjusted;
  for (auto* c : all) {
    if (std::string(CPLGetXMLValue(c, "class", "")) == "adjusted") adjusted.push_back(c);
  }
  if (adjusted.size() == 1) return adjusted.front();
  throw InputError(fmt::format("{}: {} <calibration> elements (several sensors); export the calibration of "
                               "one camera (Tools > Camera Calibration > Export)",
                               where(file), all.size()));
}

// The text of a child element, or of an attribute when `attribute`; empty when absent.
std::optional<std::string> text_of(CPLXMLNode* node, const char* path) {
  const char* v = CPLGetXMLValue(node, path, nullptr);
  if (!v) return std::nullopt;
  return std::string(v);
}

double number(CPLXMLNode* cal, const char* element, const fs::path& file, std::optional<double> fallback) {
  const auto text = text_of(cal, element);
  if (!text) {
    if (fallback) return *fallback;
    throw InputError(fmt::format("{}: <calibration>/<{}> is missing", where(file), element));
  }
  char* end = nullptr;
  const double v = std::strtod(text->c_str(), &end);
  if (text->empty() || end == text->c_str() || *end != '\0' || !std::isfinite(v)) {
    throw InputError(fmt::format("{}: <calibration>/<{}> '{}' is not a number", where(file), element, *text));
  }
  return v;
}

int image_size(CPLXMLNode* cal, const char* element, const fs::path& file) {
  // <width> in a calibration export; <resolution width="..."> in cameras.xml.
  const std::string attribute = std::string("resolution.") + element;
  const char* path = text_of(cal, element) ? element : attribute.c_str();
  if (!text_of(cal, path)) {
    throw InputError(fmt::format("{}: <calibration>/<{}> is missing", where(file), element));
  }
  const double v = number(cal, path, file, std::nullopt);
  if (v <= 0 || v != std::floor(v) || v > std::numeric_limits<int>::max()) {
    throw InputError(fmt::format("{}: <calibration>/<{}> {} must be a positive whole number of pixels",
                                 where(file), element, v));
  }
  return int(v);
}

CameraModel projection(CPLXMLNode* cal, const fs::path& file) {
  // <projection> in a calibration export, type="..." in cameras.xml.
  const std::string name = text_of(cal, "projection").value_or(text_of(cal, "type").value_or("frame"));
  if (name == "frame") return CameraModel::brown;
  if (name == "fisheye") return CameraModel::fisheye;
  throw InputError(fmt::format("{}: <calibration>/<projection> '{}' is not supported (frame or fisheye)",
                               where(file), name));
}

void refuse_nonzero(double v, const char* element, const char* why, const fs::path& file) {
  if (v != 0.0) {
    throw InputError(fmt::format("{}: <calibration>/<{}> = {} {}; recalibrate in Metashape with {} fixed at 0",
                                 where(file), element, v, why, element));
  }
}

}  // namespace

CalibrationFile read_metashape(const fs::path& file) {
  const XmlTree tree = parse_xml(file);
  CPLXMLNode* cal = find_calibration(tree.get(), file);
  CalibrationFile out;
  out.format = "metashape";
  Intrinsics& k = out.intrinsics;
  const CameraModel model = projection(cal, file);
  k.width = image_size(cal, "width", file);
  k.height = image_size(cal, "height", file);
  const double f = number(cal, "f", file, std::nullopt);
  const double cx = number(cal, "cx", file, 0.0);
  const double cy = number(cal, "cy", file, 0.0);
  const double b1 = number(cal, "b1", file, 0.0);
  const double b2 = number(cal, "b2", file, 0.0);
  const double K[4] = {number(cal, "k1", file, 0.0), number(cal, "k2", file, 0.0), number(cal, "k3", file, 0.0),
                       number(cal, "k4", file, 0.0)};
  const double P[4] = {number(cal, "p1", file, 0.0), number(cal, "p2", file, 0.0), number(cal, "p3", file, 0.0),
                       number(cal, "p4", file, 0.0)};
  if (f <= 0) throw InputError(fmt::format("{}: <calibration>/<f> = {} px must be positive", where(file), f));

  // Principal point: offset from the centre, corner origin -> absolute, pixel-centre origin.
  k.cx = k.width / 2.0 + cx - 0.5;
  k.cy = k.height / 2.0 + cy - 0.5;
  k.fx = f + b1;
  k.fy = f;
  if (b1 != 0.0) out.notes.push_back(fmt::format("b1 = {} (affinity) taken as fx = f + b1 = {} px", b1, k.fx));
  const double max_skew_px = std::abs(b2) * (k.height / 2.0) / f;
  if (max_skew_px > kMaxDroppedSkewPx) {
    throw InputError(fmt::format("{}: <calibration>/<b2> = {} (skew) moves the image edge by {:.2f} px and strata's "
                                 "camera model has no skew; recalibrate in Metashape with b2 fixed at 0",
                                 where(file), b2, max_skew_px));
  }
  if (b2 != 0.0) {
    out.notes.push_back(fmt::format("b2 = {} (skew, at most {:.3f} px at the image edge) dropped", b2, max_skew_px));
  }
  refuse_nonzero(P[2], "p3", "(higher-order tangential) is not in strata's camera models", file);
  refuse_nonzero(P[3], "p4", "(higher-order tangential) is not in strata's camera models", file);
  k.k1 = K[0];
  k.k2 = K[1];
  k.k3 = K[2];
  if (model == CameraModel::fisheye) {
    refuse_nonzero(P[0], "p1", "(tangential) is not in strata's fisheye model", file);
    refuse_nonzero(P[1], "p2", "(tangential) is not in strata's fisheye model", file);
    k.model = CameraModel::fisheye;
    k.k4 = K[3];
    return out;
  }
  refuse_nonzero(K[3], "k4", "(the r^8 term) is not in strata's brown model", file);
  // Metashape's P1 multiplies (r^2 + 2x^2), OpenCV's p2 does: swap.
  k.p1 = P[1];
  k.p2 = P[0];
  k.model = frame_model_for(k);
  if (k.p1 != 0.0 || k.p2 != 0.0) out.notes.push_back("tangential terms swapped to OpenCV's order (p1 = P2, p2 = P1)");
  return out;
}

}  // namespace strata::calibration_formats
