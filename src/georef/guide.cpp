#include "georef/guide.hpp"

#include "core/error.hpp"
#include "core/progress.hpp"
#include "core/resources.hpp"

#include <Eigen/Eigenvalues>
#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>

namespace strata {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Patches on the ground, as fractions of the marker's width. Template matching: the
// print plus 10 % of context each side. Symmetry: a window inside the print whatever
// its rotation (a square of half-width 0.35 has its corners 0.495 from the centre).
constexpr double kTemplateHalfWidth = 0.6;
constexpr double kSymmetryHalfWidth = 0.35;
constexpr int kMinHalfWindowCells = 4;   // smallest half-window that still correlates
// Symmetry search, in cells of the plane grid (about one pixel of the photo): a
// centre offset of s shows as a correlation offset of 2 s. After a template match the
// centre is within a few pixels; the second pass only polishes.
constexpr int kSymmetrySearchAfterMatch = 8;
constexpr int kSymmetryPolish = 2;
// The reference crop around a click must hold the template however foreshortened the
// clicked view is (1 / cos 75 deg = 3.9).
constexpr double kCropForeshortening = 4.0;

struct Plane {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d e1 = Eigen::Vector3d::UnitX();  // in-plane axes: grid columns, rows
  Eigen::Vector3d e2 = Eigen::Vector3d::UnitY();
};

Plane make_plane(const Eigen::Vector3d& point, const Eigen::Vector3d& normal) {
  Plane p;
  p.point = point;
  p.normal = normal.normalized();
  const Eigen::Vector3d helper = std::abs(p.normal.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
  p.e1 = p.normal.cross(helper).normalized();
  p.e2 = p.normal.cross(p.e1);
  return p;
}

// Where the ray through `pixel` meets the plane; empty behind the camera or parallel.
std::optional<Eigen::Vector3d> on_plane(const Camera& camera, const Eigen::Vector2d& pixel, const Plane& plane) {
  const Eigen::Vector3d c = camera.pose.centre();
  const Eigen::Vector3d d = camera.ray(pixel);
  const double den = plane.normal.dot(d);
  if (std::abs(den) < 1e-9) return std::nullopt;
  const double lambda = plane.normal.dot(plane.point - c) / den;
  if (lambda <= 0) return std::nullopt;
  return c + lambda * d;
}

// metres per pixel at X: depth / focal length.
double ground_pixel(const Camera& camera, const Eigen::Vector3d& X) {
  return camera.pose.to_camera(X).z() / camera.intrinsics.fx;
}

// The local ground under a marker: principal axis of least spread of the sparse points
// near it, turned towards the cameras that see it; the site's vertical when too few.
Plane local_ground(const Eigen::Vector3d& X, const std::vector<Eigen::Vector3d>& points,
                   const std::vector<Eigen::Vector3d>& view_centres, const MarkerGuideOptions& options,
                   int* used) {
  std::vector<Eigen::Vector3d> near;
  for (const auto& p : points) {
    if ((p - X).norm() <= options.plane_radius_m) near.push_back(p);
  }
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  *used = 0;
  if (int(near.size()) >= options.min_plane_points) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : near) mean += p;
    mean /= double(near.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : near) cov += (p - mean) * (p - mean).transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    normal = eig.eigenvectors().col(0);  // eigenvalues ascending
    *used = int(near.size());
  }
  Eigen::Vector3d towards = Eigen::Vector3d::Zero();
  for (const auto& c : view_centres) towards += (c - X).normalized();
  if (normal.dot(towards) < 0) normal = -normal;
  return make_plane(X, normal);
}

// A part of a photo (grey levels as float) and the photo pixel of its (0, 0).
struct PhotoCrop {
  cv::Mat grey;
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();
};

cv::Mat read_grey(const GuidePhoto& photo) {
  cv::Mat img = cv::imread(photo.path.string(), cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw IoError(fmt::format("{}: cannot read the photo {}", photo.path.string(), photo.name));
  cv::Mat grey;
  img.convertTo(grey, CV_32F);
  return grey;
}

PhotoCrop crop_around(const cv::Mat& grey, const Eigen::Vector2d& centre, double radius_px) {
  const int x0 = std::max(0, int(std::floor(centre.x() - radius_px)));
  const int y0 = std::max(0, int(std::floor(centre.y() - radius_px)));
  const int x1 = std::min(grey.cols, int(std::ceil(centre.x() + radius_px)) + 1);
  const int y1 = std::min(grey.rows, int(std::ceil(centre.y() + radius_px)) + 1);
  PhotoCrop crop;
  if (x1 <= x0 || y1 <= y0) return crop;
  crop.grey = grey(cv::Rect(x0, y0, x1 - x0, y1 - y0)).clone();
  crop.origin = {double(x0), double(y0)};
  return crop;
}

// Grey levels sampled on the plane and which of them lie inside the photo.
struct Samples {
  cv::Mat values;  // CV_32F
  cv::Mat valid;   // CV_8U, 1 = inside the photo
  int invalid = 0;
};

// Samples the photo on a (2 r + 1)^2 grid of the plane centred at `centre`: column a,
// row b is centre + cell ((a - r) e1 + (b - r) e2) (metres), seen through `camera`.
// This is the photo warped by the plane-induced homography (distortion included).
// Samples outside the crop are marked invalid (a marker at the photo's border is
// still found from the part that shows); false when behind the camera.
bool sample_on_plane(const PhotoCrop& crop, const Camera& camera, const Plane& plane,
                     const Eigen::Vector3d& centre, double cell, int r, Samples* out) {
  if (crop.grey.empty()) return false;
  const int n = 2 * r + 1;
  cv::Mat mx(n, n, CV_32F), my(n, n, CV_32F);
  out->valid = cv::Mat(n, n, CV_8U);
  out->invalid = 0;
  for (int b = 0; b < n; ++b) {
    for (int a = 0; a < n; ++a) {
      const Eigen::Vector3d P = centre + cell * (double(a - r) * plane.e1 + double(b - r) * plane.e2);
      const auto px = camera.project(P);
      if (!px) return false;
      const double x = px->x() - crop.origin.x(), y = px->y() - crop.origin.y();
      const bool inside = x >= 0 && y >= 0 && x <= crop.grey.cols - 1 && y <= crop.grey.rows - 1;
      out->valid.at<std::uint8_t>(b, a) = inside ? 1 : 0;
      out->invalid += inside ? 0 : 1;
      mx.at<float>(b, a) = inside ? float(x) : -1.0f;
      my.at<float>(b, a) = inside ? float(y) : -1.0f;
    }
  }
  cv::remap(crop.grey, out->values, mx, my, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  return true;
}

Samples central_half_turn(const Samples& s, int m, int r) {
  const cv::Rect block(m, m, 2 * r + 1, 2 * r + 1);
  Samples t;
  cv::flip(s.values(block), t.values, -1);
  cv::flip(s.valid(block), t.valid, -1);
  t.invalid = int(t.valid.total()) - cv::countNonZero(t.valid);
  return t;
}

// Normalised cross-correlation over the pairs valid in both (at least a third of the
// template), for windows that reach past the photo's border; -1 where undefined.
cv::Mat masked_ncc(const Samples& search, const Samples& templ) {
  const int th = templ.values.rows, tw = templ.values.cols;
  cv::Mat res(search.values.rows - th + 1, search.values.cols - tw + 1, CV_32F, cv::Scalar(-1));
  const int need = int(templ.values.total()) / 3;
  for (int oy = 0; oy < res.rows; ++oy) {
    for (int ox = 0; ox < res.cols; ++ox) {
      double n = 0, sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
      for (int y = 0; y < th; ++y) {
        for (int x = 0; x < tw; ++x) {
          if (!templ.valid.at<std::uint8_t>(y, x) || !search.valid.at<std::uint8_t>(oy + y, ox + x)) continue;
          const double a = templ.values.at<float>(y, x), b = search.values.at<float>(oy + y, ox + x);
          n += 1;
          sa += a;
          sb += b;
          saa += a * a;
          sbb += b * b;
          sab += a * b;
        }
      }
      if (n < need) continue;
      const double va = saa - sa * sa / n, vb = sbb - sb * sb / n;
      if (va <= 0 || vb <= 0) continue;
      res.at<float>(oy, ox) = float((sab - sa * sb / n) / std::sqrt(va * vb));
    }
  }
  return res;
}

// Vertex of the parabola through (-1, l), (0, c), (1, r); 0 when c is no maximum.
double parabola_vertex(double l, double c, double r) {
  const double den = l - 2 * c + r;
  if (den >= 0) return 0;
  return std::clamp(0.5 * (l - r) / den, -0.5, 0.5);
}

struct Peak {
  Eigen::Vector2d offset = Eigen::Vector2d::Zero();  // cells, template centre vs search centre
  double score = -1;
  bool interior = false;  // false: the peak is on the window's edge (the match lies beyond)
};

Peak correlation_peak(const Samples& search, const Samples& templ) {
  cv::Mat res;
  if (search.invalid == 0 && templ.invalid == 0) {
    cv::matchTemplate(search.values, templ.values, res, cv::TM_CCOEFF_NORMED);
  } else {
    res = masked_ncc(search, templ);
  }
  double best = 0;
  cv::Point at;
  cv::minMaxLoc(res, nullptr, &best, nullptr, &at);
  Peak p;
  p.score = best;
  p.interior = at.x > 0 && at.y > 0 && at.x < res.cols - 1 && at.y < res.rows - 1;
  double sx = 0, sy = 0;
  if (p.interior) {
    sx = parabola_vertex(res.at<float>(at.y, at.x - 1), res.at<float>(at.y, at.x), res.at<float>(at.y, at.x + 1));
    sy = parabola_vertex(res.at<float>(at.y - 1, at.x), res.at<float>(at.y, at.x), res.at<float>(at.y + 1, at.x));
  }
  p.offset = {at.x + sx - (res.cols - 1) / 2.0, at.y + sy - (res.rows - 1) / 2.0};
  return p;
}

struct Centre {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  double score = -1;
  bool ok = false;
};

// The centre of point symmetry near `start`: the window (half-width r cells) is
// correlated with its half-turn over +-search cells; matching at offset d pairs
// I(s + d + u) with I(s - u), so the centre is s + d / 2. A second, short pass from
// there polishes the estimate (the window then sits on the centre).
Centre centre_of_symmetry(const PhotoCrop& crop, const Camera& camera, const Plane& plane,
                          const Eigen::Vector3d& start, double cell, int r, int search) {
  Centre c;
  c.point = start;
  for (int m : {search, kSymmetryPolish}) {
    Samples s;
    if (!sample_on_plane(crop, camera, plane, c.point, cell, r + m, &s)) return c;
    const Peak p = correlation_peak(s, central_half_turn(s, m, r));
    c.score = p.score;
    if (!p.interior) return c;
    c.point += 0.5 * cell * (p.offset.x() * plane.e1 + p.offset.y() * plane.e2);
  }
  c.ok = true;
  return c;
}

int half_window(double half_width_m, double cell) {
  return std::max(kMinHalfWindowCells, int(std::lround(half_width_m / cell)));
}

// The marker triangulated from views; no gates (the guide applies its own).
TriangulationResult triangulate(const std::vector<Camera>& cameras, const std::vector<Eigen::Vector2d>& pixels) {
  TriangulationOptions o;
  o.min_angle_deg = 0;
  o.max_error_px = std::numeric_limits<double>::infinity();
  o.refine = true;
  return triangulate_views(cameras, pixels, o);
}

// One position of the marker in a photo: a refined click or a guided candidate.
struct Sighting {
  int photo = -1;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
  int click = -1;  // index into the clicks, -1 for a guided candidate
  double score = 0, symmetry = 0;
  bool kept = true;
  double residual_px = 0;
};

// Per marker, across the stages.
struct MarkerWork {
  const GuideMarker* marker = nullptr;
  MarkerGuideResult result;
  Plane plane;
  std::vector<PhotoCrop> click_crops;          // per click: the photo around it
  std::vector<Eigen::Vector3d> click_points;   // per click: its refined position on the plane
  std::vector<Sighting> sightings;
  bool usable = false;
};

void refine_clicks(const MarkerGuideOptions& options, const GuideInput& input, std::vector<MarkerWork>& work) {
  std::map<int, std::vector<std::pair<MarkerWork*, int>>> by_photo;
  for (auto& w : work) {
    if (!w.usable) continue;
    w.click_crops.resize(w.marker->clicks.size());
    for (std::size_t k = 0; k < w.marker->clicks.size(); ++k) by_photo[w.marker->clicks[k].photo].push_back({&w, int(k)});
  }
  for (const auto& [photo, clicks] : by_photo) {
    check_cancelled();
    const GuidePhoto& ph = input.photos[std::size_t(photo)];
    const cv::Mat grey = read_grey(ph);
    for (const auto& [w, k] : clicks) {
      const GuideClick& click = w->marker->clicks[std::size_t(k)];
      RefinedClick& rc = w->result.clicks[std::size_t(k)];
      const double cell = ground_pixel(ph.camera, w->result.position);
      const double radius_px = kCropForeshortening * kTemplateHalfWidth * options.marker_size_m / cell +
                               4.0 * options.search_px + 4;
      w->click_crops[std::size_t(k)] = crop_around(grey, click.pixel, radius_px);
      if (!options.centre_on_symmetry) continue;
      const auto start = on_plane(ph.camera, click.pixel, w->plane);
      if (!start) continue;
      const Centre c = centre_of_symmetry(w->click_crops[std::size_t(k)], ph.camera, w->plane, *start, cell,
                                          half_window(kSymmetryHalfWidth * options.marker_size_m, cell),
                                          2 * options.search_px);
      rc.symmetry = c.score;
      if (!c.ok || c.score < options.min_symmetry) continue;
      const auto px = ph.camera.project(c.point);
      if (!px) continue;
      rc.refined = *px;
      rc.refined_ok = true;
      rc.moved_px = (rc.refined - rc.clicked).norm();
    }
  }
}

// Photos (without a click or a detection of the marker) whose view holds the marker
// and faces its ground.
std::vector<int> predict_photos(const MarkerGuideOptions& options, const GuideInput& input, const MarkerWork& w) {
  std::vector<int> out;
  const double cos_max = std::cos(options.max_view_angle_deg * kPi / 180.0);
  const double border = 0.5;  // pixels: the centre inside the photo (partial windows are handled)
  for (int j = 0; j < int(input.photos.size()); ++j) {
    const auto& m = *w.marker;
    const auto clicked = std::find_if(m.clicks.begin(), m.clicks.end(), [j](const GuideClick& c) { return c.photo == j; });
    if (clicked != m.clicks.end()) continue;
    if (std::find(m.detected_in.begin(), m.detected_in.end(), j) != m.detected_in.end()) continue;
    const Camera& cam = input.photos[std::size_t(j)].camera;
    const auto px = cam.project(w.result.position);
    if (!px) continue;
    if (px->x() < border || px->y() < border || px->x() > cam.intrinsics.width - 1 - border ||
        px->y() > cam.intrinsics.height - 1 - border)
      continue;
    const Eigen::Vector3d view = (cam.pose.centre() - w.result.position).normalized();
    if (view.dot(w.plane.normal) < cos_max) continue;
    out.push_back(j);
  }
  return out;
}

// The click whose view direction is closest to the target's: the least warped appearance.
int reference_click(const GuideInput& input, const MarkerWork& w, const Camera& target) {
  const Eigen::Vector3d X = w.result.position;
  const Eigen::Vector3d to_target = (target.pose.centre() - X).normalized();
  int best = -1;
  double best_dot = -2;
  for (std::size_t k = 0; k < w.marker->clicks.size(); ++k) {
    if (w.click_crops[k].grey.empty()) continue;
    const Camera& c = input.photos[std::size_t(w.marker->clicks[k].photo)].camera;
    const double d = (c.pose.centre() - X).normalized().dot(to_target);
    if (d > best_dot) {
      best_dot = d;
      best = int(k);
    }
  }
  return best;
}

// Finds one marker in one photo: template match of the clicked appearance on the
// ground plane, then its centre of symmetry.
void find_in_photo(const MarkerGuideOptions& options, const GuideInput& input, int j, const PhotoCrop& photo,
                   MarkerWork& w) {
  const Camera& cam = input.photos[std::size_t(j)].camera;
  const int k = reference_click(input, w, cam);
  if (k < 0) return;
  const Camera& ref_cam = input.photos[std::size_t(w.marker->clicks[std::size_t(k)].photo)].camera;
  const Eigen::Vector3d& ref_point = w.click_points[std::size_t(k)];
  const double cell = ground_pixel(cam, w.result.position);
  const int rt = half_window(kTemplateHalfWidth * options.marker_size_m, cell);
  Samples templ, search;
  if (!sample_on_plane(w.click_crops[std::size_t(k)], ref_cam, w.plane, ref_point, cell, rt, &templ) ||
      !sample_on_plane(photo, cam, w.plane, ref_point, cell, rt + options.search_px, &search)) {
    w.result.rejected.push_back({j, "at the image edge", 0});
    return;
  }
  const Peak p = correlation_peak(search, templ);
  if (!p.interior || p.score < options.min_score) {
    w.result.rejected.push_back({j, "no match", p.score});
    return;
  }
  Sighting s;
  s.photo = j;
  s.score = p.score;
  Eigen::Vector3d point = ref_point + cell * (p.offset.x() * w.plane.e1 + p.offset.y() * w.plane.e2);
  if (options.centre_on_symmetry) {
    const Centre c = centre_of_symmetry(photo, cam, w.plane, point, cell,
                                        half_window(kSymmetryHalfWidth * options.marker_size_m, cell),
                                        kSymmetrySearchAfterMatch);
    s.symmetry = c.score;
    if (!c.ok || c.score < options.min_symmetry) {
      w.result.rejected.push_back({j, "not symmetric", c.score});
      return;
    }
    point = c.point;
  }
  const auto px = cam.project(point);
  if (!px) return;
  s.pixel = *px;
  w.sightings.push_back(s);
}

// Triangulates from the kept sightings, dropping the worst while it exceeds the gate.
TriangulationResult triangulate_kept(const GuideInput& input, std::vector<Sighting>& sightings, double gate_px) {
  TriangulationResult tri;
  for (;;) {
    std::vector<Camera> cams;
    std::vector<Eigen::Vector2d> px;
    std::vector<std::size_t> index;
    for (std::size_t i = 0; i < sightings.size(); ++i) {
      if (!sightings[i].kept) continue;
      cams.push_back(input.photos[std::size_t(sightings[i].photo)].camera);
      px.push_back(sightings[i].pixel);
      index.push_back(i);
    }
    if (cams.size() < 2) return TriangulationResult{};
    tri = triangulate(cams, px);
    if (!std::isfinite(tri.max_error_px)) return TriangulationResult{};
    std::size_t worst = 0;
    double worst_px = -1;
    for (std::size_t q = 0; q < cams.size(); ++q) {
      const double e = (*cams[q].project(tri.X) - px[q]).norm();
      sightings[index[q]].residual_px = e;
      if (e > worst_px) {
        worst_px = e;
        worst = index[q];
      }
    }
    if (worst_px <= gate_px || cams.size() <= 2) return tri;
    sightings[worst].kept = false;
  }
}

void conclude(const MarkerGuideOptions& options, const GuideInput& input, MarkerWork& w) {
  auto& r = w.result;
  const auto& clicks = w.marker->clicks;
  std::vector<Sighting> all;
  for (std::size_t k = 0; k < clicks.size(); ++k) {
    Sighting s;
    s.photo = clicks[k].photo;
    s.pixel = r.clicks[k].refined;
    s.click = int(k);
    all.push_back(s);
  }
  all.insert(all.end(), w.sightings.begin(), w.sightings.end());
  const TriangulationResult tri = triangulate_kept(input, all, options.gate_px);
  if (tri.views < 2 || !tri.X.allFinite()) {
    r.triangulated = false;
    r.message = "the refined positions do not meet in one point";
    return;
  }
  r.position = tri.X;
  double sum2 = 0;
  int n = 0;
  for (const auto& s : all) {
    if (s.kept) {
      sum2 += s.residual_px * s.residual_px;
      ++n;
    }
    if (s.click >= 0) continue;
    if (s.kept) {
      r.added.push_back({s.photo, s.pixel, s.score, s.symmetry, s.residual_px});
    } else {
      r.rejected.push_back({s.photo, "disagrees with the rays", s.residual_px});
    }
  }
  r.rmse_px = n > 0 ? std::sqrt(sum2 / n) : 0;
  // Each click against where the other kept rays meet.
  for (std::size_t k = 0; k < clicks.size(); ++k) {
    std::vector<Camera> cams;
    std::vector<Eigen::Vector2d> px;
    for (const auto& s : all) {
      if (!s.kept || s.click == int(k)) continue;
      cams.push_back(input.photos[std::size_t(s.photo)].camera);
      px.push_back(s.pixel);
    }
    RefinedClick& rc = r.clicks[k];
    rc.to_rays_px = std::numeric_limits<double>::quiet_NaN();
    if (cams.size() < 2) continue;
    const TriangulationResult others = triangulate(cams, px);
    const Camera& cam = input.photos[std::size_t(clicks[k].photo)].camera;
    const auto proj = cam.project(others.X);
    if (!proj) continue;
    rc.to_rays_px = (*proj - rc.clicked).norm();
    rc.far = rc.to_rays_px > options.far_click_px;
  }
}

void start_marker(const MarkerGuideOptions& options, const GuideInput& input, MarkerWork& w) {
  auto& r = w.result;
  const auto& clicks = w.marker->clicks;
  std::vector<Camera> cams;
  std::vector<Eigen::Vector2d> px;
  std::vector<Eigen::Vector3d> centres;
  for (const auto& c : clicks) {
    cams.push_back(input.photos[std::size_t(c.photo)].camera);
    px.push_back(c.pixel);
    centres.push_back(cams.back().pose.centre());
    RefinedClick rc;
    rc.photo = c.photo;
    rc.clicked = rc.refined = c.pixel;
    r.clicks.push_back(rc);
  }
  const TriangulationResult tri = triangulate(cams, px);
  if (!std::isfinite(tri.max_error_px) || !tri.X.allFinite()) {
    r.message = "the rays of its clicks do not meet in front of the cameras";
    return;
  }
  r.position = tri.X;
  r.triangulated = true;
  w.plane = local_ground(tri.X, input.sparse_points, centres, options, &r.plane_points);
  r.normal = w.plane.normal;
  w.usable = true;
}

// After the clicks are refined: the marker from them, the plane through it, and the
// clicks' positions on that plane (the templates' centres).
void anchor_marker(const GuideInput& input, MarkerWork& w) {
  auto& r = w.result;
  const auto& clicks = w.marker->clicks;
  std::vector<Camera> cams;
  std::vector<Eigen::Vector2d> px;
  for (std::size_t k = 0; k < clicks.size(); ++k) {
    cams.push_back(input.photos[std::size_t(clicks[k].photo)].camera);
    px.push_back(r.clicks[k].refined);
  }
  const TriangulationResult tri = triangulate(cams, px);
  if (std::isfinite(tri.max_error_px) && tri.X.allFinite()) r.position = tri.X;
  w.plane = make_plane(r.position, w.plane.normal);
  w.click_points.clear();
  for (std::size_t k = 0; k < clicks.size(); ++k) {
    const auto p = on_plane(cams[k], r.clicks[k].refined, w.plane);
    w.click_points.push_back(p ? *p : r.position);
  }
}

}  // namespace

void MarkerGuideOptions::validate() const {
  auto require = [](bool ok, const char* field, double value, const char* range) {
    if (!ok) throw InputError(fmt::format("markers guide: option {} must be {} (got {})", field, range, value));
  };
  require(marker_size_m >= 0.01 && marker_size_m <= 2.0, "marker_size_m", marker_size_m, "0.01..2 m");
  require(min_score > -1 && min_score < 1, "min_score", min_score, "between -1 and 1");
  require(min_symmetry > -1 && min_symmetry < 1, "min_symmetry", min_symmetry, "between -1 and 1");
  require(search_px >= 2 && search_px <= 200, "search_px", search_px, "2..200 pixels");
  require(gate_px > 0, "gate_px", gate_px, "> 0 pixels");
  require(far_click_px > 0, "far_click_px", far_click_px, "> 0 pixels");
  require(max_view_angle_deg > 0 && max_view_angle_deg < 90, "max_view_angle_deg", max_view_angle_deg,
          "between 0 and 90 degrees");
  require(plane_radius_m > 0, "plane_radius_m", plane_radius_m, "> 0 m");
  require(min_plane_points >= 3, "min_plane_points", min_plane_points, ">= 3");
}

MarkerGuideSummary guide_markers(const MarkerGuideOptions& options, const GuideInput& input) {
  options.validate();
  Stopwatch sw;
  std::vector<MarkerWork> work(input.markers.size());
  for (std::size_t i = 0; i < input.markers.size(); ++i) {
    const GuideMarker& m = input.markers[i];
    if (m.clicks.size() < 2) {
      throw InputError(fmt::format("markers guide: marker {} has {} click(s) in registered photos; it needs "
                                   "clicks in at least 2", m.name, m.clicks.size()));
    }
    work[i].marker = &m;
    work[i].result.name = m.name;
    start_marker(options, input, work[i]);
  }
  refine_clicks(options, input, work);
  std::map<int, std::vector<MarkerWork*>> wanted;  // photo -> markers sought there
  for (auto& w : work) {
    if (!w.usable) continue;
    anchor_marker(input, w);
    for (int j : predict_photos(options, input, w)) {
      wanted[j].push_back(&w);
      w.result.predicted++;
    }
  }
  {
    Progress progress("markers guide", wanted.size());
    for (const auto& [j, markers] : wanted) {
      check_cancelled();
      PhotoCrop photo;
      photo.grey = read_grey(input.photos[std::size_t(j)]);
      for (MarkerWork* w : markers) find_in_photo(options, input, j, photo, *w);
      progress.step();
    }
    progress.finish();
  }
  MarkerGuideSummary summary;
  for (auto& w : work) {
    if (w.usable) conclude(options, input, w);
    summary.added += int(w.result.added.size());
    summary.markers.push_back(std::move(w.result));
  }
  summary.seconds = sw.seconds();
  return summary;
}

}  // namespace strata
