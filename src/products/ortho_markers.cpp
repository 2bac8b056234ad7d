#include "products/ortho_markers.hpp"

#include "core/error.hpp"
#include "core/resources.hpp"
#include "core/statistics.hpp"

#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace strata {
namespace {
// A missed marker counts as fully covered from this share of coloured cells around it.
constexpr double kMinCoveredShare = 0.9;

}  // namespace

void OrthoMarkerCheckOptions::validate() const {
  targets.validate();
  naming.validate();
  if (!(tolerance_px > 0)) {
    throw InputError(fmt::format("products.ortho_markers: tolerance_px must be > 0 pixels, got {}", tolerance_px));
  }
  if (!(coverage_radius_m >= 0)) {
    throw InputError(
        fmt::format("products.ortho_markers: coverage_radius_m must be >= 0 metres, got {}", coverage_radius_m));
  }
  if (!(max_source_pixel_cells > 0)) {
    throw InputError(fmt::format("products.ortho_markers: max_source_pixel_cells must be > 0, got {}",
                                 max_source_pixel_cells));
  }
  if (tile_cells < 64) throw InputError(fmt::format("products.ortho_markers: tile_cells must be >= 64, got {}", tile_cells));
  if (!(tile_margin_m > 0)) {
    throw InputError(fmt::format("products.ortho_markers: tile_margin_m must be > 0 metres, got {}", tile_margin_m));
  }
  if (fill_holes_max_cells < 0) {
    throw InputError(
        fmt::format("products.ortho_markers: fill_holes_max_cells must be >= 0 cells, got {}", fill_holes_max_cells));
  }
  if (upsample.empty()) throw InputError("products.ortho_markers: upsample needs at least one factor");
  for (int f : upsample) {
    if (f < 1 || f > 8) throw InputError(fmt::format("products.ortho_markers: upsample factors must be in [1, 8], got {}", f));
  }
}

const char* to_string(OrthoMarkerStatus s) {
  switch (s) {
    case OrthoMarkerStatus::detected:
      return "detected";
    case OrthoMarkerStatus::outside:
      return "outside";
    case OrthoMarkerStatus::not_seen:
      return "not_seen";
    case OrthoMarkerStatus::partly_seen:
      return "partly_seen";
    case OrthoMarkerStatus::coarse:
      return "coarse";
    case OrthoMarkerStatus::not_detected:
      return "not_detected";
  }
  return "?";
}

namespace {

// A target found at one or more enlargements; centre in the site frame.
struct Target {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  int scales = 0;
  Eigen::Vector2d centre() const { return sum / scales; }
};
using TargetsByName = std::map<std::string, std::vector<Target>>;

// Grey detection image. Cells no photo coloured become mid-grey rather than
// black, so the edge of the coverage does not look like a target's black border.
// Small holes (a few cells no photo coloured, e.g. inside a target) are
// inpainted from their surroundings; larger unseen areas become mid-grey.
cv::Mat detection_image(const RgbaRaster& ortho, const OrthoMarkerCheckOptions& options) {
  const RasterGrid& g = ortho.grid;
  cv::Mat rgba(g.height, g.width, CV_8UC4, const_cast<std::uint8_t*>(ortho.rgba.data()));
  cv::Mat grey;
  cv::cvtColor(rgba, grey, cv::COLOR_RGBA2GRAY);
  cv::Mat holes(g.height, g.width, CV_8UC1, cv::Scalar(0));
  for (int r = 0; r < g.height; ++r) {
    for (int c = 0; c < g.width; ++c) {
      if (ortho.rgba[4 * g.index(c, r) + 3] == 0) holes.at<std::uint8_t>(r, c) = 255;
    }
  }
  cv::Mat small_holes(g.height, g.width, CV_8UC1, cv::Scalar(0));
  if (options.fill_holes_max_cells > 0 && cv::countNonZero(holes) > 0) {
    cv::Mat labels, stats, centroids;
    const int n = cv::connectedComponentsWithStats(holes, labels, stats, centroids, 8, CV_32S);
    for (int r = 0; r < g.height; ++r) {
      for (int c = 0; c < g.width; ++c) {
        const int l = labels.at<int>(r, c);
        if (l > 0 && l < n && stats.at<int>(l, cv::CC_STAT_AREA) <= options.fill_holes_max_cells)
          small_holes.at<std::uint8_t>(r, c) = 255;
      }
    }
  }
  grey.setTo(128, holes);
  if (cv::countNonZero(small_holes) > 0) {
    // Fast-marching inpainting (Telea 2004) fills the small holes from the outside in;
    // a radius of 2 cells reaches across the narrowest ones and no further.
    cv::Mat filled;
    cv::inpaint(grey, small_holes, filled, 2.0, cv::INPAINT_TELEA);
    grey = filled;
  }
  return grey;
}

// Targets by marker name, centres in the site frame. With the pixel-centre
// convention, detection pixel u at enlargement s of a tile read from column x0 is
// orthophoto column x0 + (u + 0.5) / s - 0.5, whose centre lies at
// x_min + (column + 0.5) * cell. Detections of one name within `same_target_m` of
// each other (found at several enlargements) are one target, placed at their mean.
// The orthophoto is searched in tiles of tile_cells x tile_cells cells, each read
// with a margin of tile_margin_m around it and enlarged on its own, so memory stays
// bounded whatever the orthophoto's size; a target counts in the tile that holds
// its centre (the margin lets a target across a tile edge be seen whole).
TargetsByName find_targets(const cv::Mat& grey, const RasterGrid& g, const OrthoMarkerCheckOptions& options,
                           const std::vector<SurveyedMarker>& markers, std::vector<int>& unknown_ids) {
  // Every enlargement is searched as it is: the photos' downscaling for detection
  // (max_detection_size) would undo it.
  TargetOptions targets = options.targets;
  targets.max_detection_size = 0;
  std::map<std::string, bool> surveyed;
  for (const SurveyedMarker& m : markers) surveyed[m.name] = true;
  const double same_target_m = 0.05;
  TargetsByName by_name;
  const int tile = options.tile_cells;
  const int margin = int(std::ceil(options.tile_margin_m / g.cell));
  for (int s : options.upsample) {
    for (int r0 = 0; r0 < g.height; r0 += tile) {
      for (int c0 = 0; c0 < g.width; c0 += tile) {
        const int r1 = std::min(g.height, r0 + tile), c1 = std::min(g.width, c0 + tile);
        const cv::Rect read(cv::Point(std::max(0, c0 - margin), std::max(0, r0 - margin)),
                            cv::Point(std::min(g.width, c1 + margin), std::min(g.height, r1 + margin)));
        cv::Mat big;  // continuous, as detect_targets needs
        if (s > 1) {
          cv::resize(grey(read), big, cv::Size(read.width * s, read.height * s), 0, 0, cv::INTER_CUBIC);
        } else {
          big = grey(read).clone();
        }
        for (const TargetDetection& d : detect_targets(targets, big.ptr<std::uint8_t>(), big.cols, big.rows)) {
          // Orthophoto column and row of the centre (pixel-centre convention).
          const double col = read.x + (d.centre.x() + 0.5) / s - 0.5, row = read.y + (d.centre.y() + 0.5) / s - 0.5;
          if (col < c0 - 0.5 || col >= c1 - 0.5 || row < r0 - 0.5 || row >= r1 - 0.5) continue;  // another tile's
          const std::string name = target_name(options.naming, d.id);
          if (name.empty() || !surveyed.count(name)) {
            if (std::find(unknown_ids.begin(), unknown_ids.end(), d.id) == unknown_ids.end())
              unknown_ids.push_back(d.id);
            continue;
          }
          const Eigen::Vector2d p(g.x_min + (col + 0.5) * g.cell, g.y_max - (row + 0.5) * g.cell);
          std::vector<Target>& found = by_name[name];
          auto same = std::find_if(found.begin(), found.end(),
                                   [&](const Target& t) { return (t.centre() - p).norm() < same_target_m; });
          if (same == found.end()) same = found.insert(found.end(), Target{});
          same->sum += p;
          ++same->scales;
        }
      }
    }
  }
  std::sort(unknown_ids.begin(), unknown_ids.end());
  return by_name;
}

// One surveyed marker against what was found: its offset when detected, else why
// not, from the cells within coverage_radius_m of the survey (how many are coloured
// — cells off the grid count as not — and the photos' pixel size there).
OrthoMarkerOffset judge_marker(const SurveyedMarker& m, const TargetsByName& by_name, const RgbaRaster& ortho,
                               const OrthoMarkerCheckOptions& options, const std::vector<float>* source_pixel_m) {
  const RasterGrid& g = ortho.grid;
  OrthoMarkerOffset o;
  o.name = m.name;
  o.kind = m.kind;
  o.surveyed = m.position.head<2>();
  const int k = int(std::ceil(options.coverage_radius_m / g.cell));
  const double col = std::floor((o.surveyed.x() - g.x_min) / g.cell);
  const double row = std::floor((g.y_max - o.surveyed.y()) / g.cell);
  const bool on_grid = col >= 0 && row >= 0 && col < g.width && row < g.height;
  std::size_t inside = 0, coloured = 0;
  std::vector<float> pixel_sizes;
  for (int dr = -k; dr <= k; ++dr) {
    for (int dc = -k; dc <= k; ++dc) {
      if (dr * dr + dc * dc > k * k) continue;
      ++inside;
      const int cc = int(col) + dc, rr = int(row) + dr;
      if (!on_grid || cc < 0 || rr < 0 || cc >= g.width || rr >= g.height) continue;
      const std::size_t i = g.index(cc, rr);
      if (ortho.rgba[4 * i + 3] == 0) continue;
      ++coloured;
      if (source_pixel_m && std::isfinite((*source_pixel_m)[i])) pixel_sizes.push_back((*source_pixel_m)[i]);
    }
  }
  if (!pixel_sizes.empty()) o.source_pixel_m = median_in_place(pixel_sizes);
  if (const auto it = by_name.find(m.name); it != by_name.end()) {
    o.status = OrthoMarkerStatus::detected;
    o.detections = int(it->second.size());
    double best = std::numeric_limits<double>::infinity();
    for (const Target& t : it->second) {
      const double dist = (t.centre() - o.surveyed).norm();
      if (dist < best) {
        best = dist;
        o.detected = t.centre();
        o.scales = t.scales;
      }
    }
    o.de_m = o.detected.x() - o.surveyed.x();
    o.dn_m = o.detected.y() - o.surveyed.y();
    o.offset_m = best;
    o.offset_px = best / g.cell;
  } else if (!on_grid) {
    o.status = OrthoMarkerStatus::outside;
  } else if (ortho.rgba[4 * g.index(int(col), int(row)) + 3] == 0) {
    o.status = OrthoMarkerStatus::not_seen;
  } else if (double(coloured) < kMinCoveredShare * double(inside)) {
    o.status = OrthoMarkerStatus::partly_seen;
  } else if (o.source_pixel_m > options.max_source_pixel_cells * g.cell) {
    o.status = OrthoMarkerStatus::coarse;
  } else {
    o.status = OrthoMarkerStatus::not_detected;
  }
  return o;
}

}  // namespace

OrthoMarkerCheck check_ortho_markers(const RgbaRaster& ortho, const std::vector<SurveyedMarker>& markers,
                                     const OrthoMarkerCheckOptions& options,
                                     const std::vector<float>* source_pixel_m) {
  options.validate();
  const RasterGrid& g = ortho.grid;
  STRATA_CHECK(g.width > 0 && g.height > 0 && ortho.rgba.size() == 4 * g.cells());
  STRATA_CHECK(!source_pixel_m || source_pixel_m->size() == g.cells(), "source pixel sizes do not match the grid");
  Stopwatch clock;
  OrthoMarkerCheck out;
  out.cell_m = g.cell;
  out.tolerance_px = options.tolerance_px;
  const TargetsByName by_name = find_targets(detection_image(ortho, options), g, options, markers, out.unknown_ids);
  double sum_sq_m = 0;
  for (const SurveyedMarker& m : markers) {
    OrthoMarkerOffset o = judge_marker(m, by_name, ortho, options, source_pixel_m);
    if (o.status == OrthoMarkerStatus::detected) {
      ++out.detected;
      if (o.offset_px > options.tolerance_px) ++out.over_tolerance;
      out.max_m = std::max(out.max_m, o.offset_m);
      sum_sq_m += o.offset_m * o.offset_m;
    }
    out.markers.push_back(std::move(o));
  }
  if (out.detected > 0) {
    out.rmse_m = std::sqrt(sum_sq_m / out.detected);
    out.rmse_px = out.rmse_m / g.cell;
    out.max_px = out.max_m / g.cell;
  }
  out.seconds = clock.seconds();
  return out;
}

}  // namespace strata
