#include "features/targets.hpp"

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/resources.hpp"

#include <opencv2/aruco.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <numeric>
#include <optional>

namespace strata {
namespace {

std::string upper(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return out;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

std::optional<cv::aruco::PREDEFINED_DICTIONARY_NAME> dictionary_by_name(std::string_view name) {
  using namespace cv::aruco;
  std::string key = upper(trim(name));
  if (key.rfind("DICT_", 0) == 0) key = key.substr(5);
  if (key.rfind("TAG", 0) == 0) key = "APRILTAG_" + key.substr(3);  // tag36h11
  static const std::pair<const char*, PREDEFINED_DICTIONARY_NAME> table[] = {
      {"4X4_50", DICT_4X4_50},       {"4X4_100", DICT_4X4_100},
      {"4X4_250", DICT_4X4_250},     {"4X4_1000", DICT_4X4_1000},
      {"5X5_50", DICT_5X5_50},       {"5X5_100", DICT_5X5_100},
      {"5X5_250", DICT_5X5_250},     {"5X5_1000", DICT_5X5_1000},
      {"6X6_50", DICT_6X6_50},       {"6X6_100", DICT_6X6_100},
      {"6X6_250", DICT_6X6_250},     {"6X6_1000", DICT_6X6_1000},
      {"7X7_50", DICT_7X7_50},       {"7X7_100", DICT_7X7_100},
      {"7X7_250", DICT_7X7_250},     {"7X7_1000", DICT_7X7_1000},
      {"ARUCO_ORIGINAL", DICT_ARUCO_ORIGINAL},
      {"APRILTAG_16H5", DICT_APRILTAG_16h5},
      {"APRILTAG_25H9", DICT_APRILTAG_25h9},
      {"APRILTAG_36H10", DICT_APRILTAG_36h10},
      {"APRILTAG_36H11", DICT_APRILTAG_36h11},
  };
  for (const auto& [n, d] : table)
    if (key == n) return d;
  return std::nullopt;
}

// Intersection of the diagonals c0-c2 and c1-c3 (homogeneous lines, H&Z 2.2.1):
// a projective map sends the square's centre there.
Eigen::Vector2d diagonal_intersection(const std::vector<Eigen::Vector2d>& c) {
  const Eigen::Vector3d l1 = c[0].homogeneous().cross(c[2].homogeneous());
  const Eigen::Vector3d l2 = c[1].homogeneous().cross(c[3].homogeneous());
  const Eigen::Vector3d p = l1.cross(l2);
  if (std::abs(p.z()) < 1e-12) {  // degenerate quad: fall back to the mean
    return 0.25 * (c[0] + c[1] + c[2] + c[3]);
  }
  return p.hnormalized();
}

}  // namespace

void TargetOptions::validate() const {
  auto fail = [](const char* field, const std::string& why) {
    throw InputError(fmt::format("targets: option {} {}", field, why));
  };
  if (!dictionary_by_name(dictionary))
    fail("dictionary", fmt::format("'{}' is not a known ArUco/AprilTag dictionary (e.g. "
                                   "DICT_4X4_50, DICT_APRILTAG_36h11)",
                                   dictionary));
  if (max_detection_size < 0 || (max_detection_size > 0 && max_detection_size < 256))
    fail("max_detection_size",
         fmt::format("must be 0 or >= 256 pixels (got {})", max_detection_size));
  if (!(min_perimeter_rate > 0 && min_perimeter_rate < 4))
    fail("min_perimeter_rate", fmt::format("must be in (0, 4) (got {})", min_perimeter_rate));
  if (!(refine_epsilon_px > 0))
    fail("refine_epsilon_px", fmt::format("must be > 0 pixels (got {})", refine_epsilon_px));
}

namespace {

std::vector<TargetDetection> detect_in_grey(const TargetOptions& options, const cv::Mat& grey,
                                            const Stopwatch& clock, TargetSummary* summary) {
  // Detection image: downscaled when the photo is large.
  cv::Mat work = grey;
  const int long_side = std::max(grey.cols, grey.rows);
  const bool downscale = options.max_detection_size > 0 && long_side > options.max_detection_size;
  if (downscale) {
    const double s = static_cast<double>(options.max_detection_size) / long_side;
    cv::resize(grey, work,
               cv::Size(std::max(1, static_cast<int>(std::lround(grey.cols * s))),
                        std::max(1, static_cast<int>(std::lround(grey.rows * s)))),
               0, 0, cv::INTER_AREA);
  }
  const double fx = static_cast<double>(grey.cols) / work.cols;  // work -> photo pixels
  const double fy = static_cast<double>(grey.rows) / work.rows;

  const auto dictionary_name = *dictionary_by_name(options.dictionary);
  const cv::Ptr<cv::aruco::Dictionary> dictionary =
      cv::aruco::getPredefinedDictionary(dictionary_name);
  cv::Ptr<cv::aruco::DetectorParameters> params = cv::aruco::DetectorParameters::create();
  params->minMarkerPerimeterRate = options.min_perimeter_rate;
  params->cornerRefinementMethod = options.refinement == TargetOptions::Refinement::apriltag
                                       ? cv::aruco::CORNER_REFINE_APRILTAG
                                       : cv::aruco::CORNER_REFINE_NONE;

  std::vector<std::vector<cv::Point2f>> corners, rejected;
  std::vector<int> ids;
  cv::aruco::detectMarkers(work, dictionary, corners, ids, params, rejected);

  std::vector<TargetDetection> out;
  out.reserve(ids.size());
  const int cells = dictionary->markerSize + 2 * params->markerBorderBits;
  for (std::size_t m = 0; m < ids.size(); ++m) {
    // Work-image corners to photo pixels (pixel-centre convention).
    std::vector<cv::Point2f> full(4);
    for (int c = 0; c < 4; ++c) {
      full[c] = cv::Point2f(static_cast<float>((corners[m][c].x + 0.5) * fx - 0.5),
                            static_cast<float>((corners[m][c].y + 0.5) * fy - 0.5));
    }
    if (options.refinement == TargetOptions::Refinement::subpixel) {
      // Window: half a marker cell (a cell is the distance to the next edge
      // inside the marker), at least 2 px so blur does not dominate, at most
      // 25 px to bound the cost.
      double side = 1e30;
      for (int c = 0; c < 4; ++c) side = std::min<double>(side, cv::norm(full[c] - full[(c + 1) % 4]));
      const int half = std::clamp(static_cast<int>(0.5 * side / cells), 2, 25);
      cv::cornerSubPix(grey, full, cv::Size(half, half), cv::Size(-1, -1),
                       cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100,
                                        options.refine_epsilon_px));
    }
    TargetDetection d;
    d.id = ids[m];
    for (const auto& p : full) d.corners.emplace_back(p.x, p.y);
    d.centre = diagonal_intersection(d.corners);
    out.push_back(std::move(d));
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const TargetDetection& a, const TargetDetection& b) { return a.id < b.id; });

  if (summary) {
    summary->detections = out.size();
    summary->rejected_candidates = rejected.size();
    summary->downscaled = downscale;
    summary->seconds = clock.seconds();
  }
  return out;
}

}  // namespace

std::vector<TargetDetection> detect_targets(const TargetOptions& options,
                                            const std::filesystem::path& image,
                                            TargetSummary* summary) {
  options.validate();
  Stopwatch clock;
  const cv::Mat grey =
      cv::imread(image.string(), cv::IMREAD_GRAYSCALE | cv::IMREAD_IGNORE_ORIENTATION);
  if (grey.empty()) throw IoError(fmt::format("targets: cannot read image {}", image.string()));
  return detect_in_grey(options, grey, clock, summary);
}

std::vector<TargetDetection> detect_targets(const TargetOptions& options, const std::uint8_t* grey, int width,
                                            int height, TargetSummary* summary) {
  options.validate();
  Stopwatch clock;
  if (grey == nullptr || width <= 0 || height <= 0)
    throw InputError(fmt::format("targets: empty image ({} x {} pixels)", width, height));
  // cv::Mat over the caller's pixels (not modified: the detector only reads them).
  const cv::Mat view(height, width, CV_8UC1, const_cast<std::uint8_t*>(grey));
  return detect_in_grey(options, view, clock, summary);
}

// ---- naming -------------------------------------------------------------------

namespace {

// Expands the rule for one id; throws InputError for a malformed placeholder.
std::string expand_rule(const std::string& rule, int id) {
  std::string out;
  bool placeholder = false;
  for (std::size_t i = 0; i < rule.size();) {
    if (rule[i] != '{') {
      if (rule[i] == '}')
        throw InputError(fmt::format("target naming: rule '{}' has an unmatched '}}'", rule));
      out += rule[i++];
      continue;
    }
    const std::size_t close = rule.find('}', i);
    if (close == std::string::npos)
      throw InputError(fmt::format("target naming: rule '{}' has an unclosed '{{'", rule));
    const std::string_view field(rule.data() + i + 1, close - i - 1);
    if (field == "id") {
      out += std::to_string(id);
    } else if (field.rfind("id:", 0) == 0) {
      std::string_view digits = field.substr(3);
      int width = 0;
      const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), width);
      if (ec != std::errc() || end != digits.data() + digits.size() || width < 1 || width > 12)
        throw InputError(fmt::format(
            "target naming: rule '{}': '{{{}}}' needs a width of 1 to 12 digits, e.g. {{id:03}}",
            rule, field));
      out += fmt::format("{:0{}d}", id, width);
    } else {
      throw InputError(fmt::format(
          "target naming: rule '{}' has an unknown placeholder '{{{}}}' (use {{id}} or {{id:N}})",
          rule, field));
    }
    placeholder = true;
    i = close + 1;
  }
  if (!placeholder)
    throw InputError(fmt::format(
        "target naming: rule '{}' has no {{id}} placeholder: every target would get the same "
        "name",
        rule));
  return out;
}

}  // namespace

void TargetNaming::validate() const {
  if (!rule.empty()) expand_rule(rule, 0);
  for (const auto& [id, name] : names) {
    if (trim(name).empty())
      throw InputError(fmt::format("target naming: target {} is mapped to an empty name", id));
  }
}

std::map<int, std::string> parse_target_names(std::string_view text) {
  std::map<int, std::string> out;
  std::size_t start = 0;
  while (start <= text.size()) {
    std::size_t comma = text.find(',', start);
    if (comma == std::string_view::npos) comma = text.size();
    const std::string_view entry = trim(text.substr(start, comma - start));
    start = comma + 1;
    if (entry.empty()) {
      if (comma == text.size()) break;
      continue;
    }
    const std::size_t eq = entry.find('=');
    if (eq == std::string_view::npos)
      throw InputError(fmt::format("target names: entry '{}' is not id=name", entry));
    const std::string_view id_text = trim(entry.substr(0, eq));
    const std::string_view name = trim(entry.substr(eq + 1));
    int id = -1;
    const auto [end, ec] = std::from_chars(id_text.data(), id_text.data() + id_text.size(), id);
    if (ec != std::errc() || end != id_text.data() + id_text.size() || id < 0)
      throw InputError(fmt::format("target names: entry '{}': '{}' is not a target id (an "
                                   "integer >= 0)",
                                   entry, id_text));
    if (name.empty())
      throw InputError(fmt::format("target names: entry '{}' has an empty name", entry));
    if (!out.emplace(id, std::string(name)).second)
      throw InputError(fmt::format("target names: target {} is mapped twice", id));
  }
  return out;
}

std::string target_name(const TargetNaming& naming, int id) {
  if (const auto it = naming.names.find(id); it != naming.names.end()) return it->second;
  if (naming.rule.empty()) return {};
  return expand_rule(naming.rule, id);
}

}  // namespace strata
