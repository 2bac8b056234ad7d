#include "products/photo_sampling.hpp"

#include "core/error.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

namespace strata {

void PhotoPixels::build_pyramid(double max_footprint_px) {
  while (double(1 << (levels.size() - 1)) < max_footprint_px && levels.back().cols >= 8 && levels.back().rows >= 8) {
    const cv::Mat& src = levels.back();
    // Even size first (the odd last row/column dropped), so that INTER_AREA is an
    // exact 2 x 2 mean and level pixel j is centred on level-0 pixel 2^l j + (2^l - 1) / 2.
    const cv::Mat even = src(cv::Rect(0, 0, src.cols & ~1, src.rows & ~1));
    cv::Mat half;
    cv::resize(even, half, cv::Size(even.cols / 2, even.rows / 2), 0, 0, cv::INTER_AREA);
    levels.push_back(half);
  }
}

void PhotoPixels::sample(double x, double y, double footprint_px, std::uint8_t out[3]) const {
  const double lod = std::clamp(std::log2(std::max(footprint_px, 1.0)) - 1.0, 0.0, double(levels.size() - 1));
  const int l0 = int(std::floor(lod));
  const int l1 = std::min(l0 + 1, int(levels.size()) - 1);
  const double t = lod - l0;
  double a[3], b[3] = {0, 0, 0};
  bilinear(l0, x, y, a);
  if (t > 0 && l1 != l0) bilinear(l1, x, y, b);
  for (int k = 0; k < 3; ++k) out[k] = std::uint8_t(std::clamp(std::lround((1 - t) * a[k] + t * b[k]), 0L, 255L));
}

void PhotoPixels::bilinear(int level, double x0, double y0, double out[3]) const {
  const cv::Mat& m = levels[std::size_t(level)];
  const double scale = 1.0 / double(1 << level);
  const double x = (x0 + 0.5) * scale - 0.5, y = (y0 + 0.5) * scale - 0.5;
  const int w = m.cols, h = m.rows;
  const int xi = std::clamp(int(std::floor(x)), 0, w - 2), yi = std::clamp(int(std::floor(y)), 0, h - 2);
  const double ax = std::clamp(x - xi, 0.0, 1.0), ay = std::clamp(y - yi, 0.0, 1.0);
  const std::uint8_t* p00 = m.ptr<std::uint8_t>(yi) + std::size_t(xi) * 3;
  const std::uint8_t* p10 = p00 + 3;
  const std::uint8_t* p01 = m.ptr<std::uint8_t>(yi + 1) + std::size_t(xi) * 3;
  const std::uint8_t* p11 = p01 + 3;
  for (int k = 0; k < 3; ++k) {
    out[k] = (1 - ay) * ((1 - ax) * p00[k] + ax * p10[k]) + ay * ((1 - ax) * p01[k] + ax * p11[k]);
  }
}

PhotoPixels load_photo(const OrthoView& v, const char* stage) {
  PhotoPixels p;
  const Intrinsics& K = v.camera.intrinsics;
  if (!v.rgb.empty()) {
    STRATA_CHECK(v.rgb.size() == std::size_t(K.width) * K.height * 3, "in-memory photo size mismatch");
    // A header over the caller's pixels; the pyramid levels are owned.
    p.levels.push_back(cv::Mat(K.height, K.width, CV_8UC3, const_cast<std::uint8_t*>(v.rgb.data())));
    return p;
  }
  // The camera model describes the sensor as stored: EXIF orientation is ignored,
  // as in feature extraction.
  // Checked first: OpenCV's imread would print a warning of its own beside our error.
  std::error_code ec;
  if (!std::filesystem::is_regular_file(v.photo, ec)) {
    throw IoError(fmt::format("{}: photo {} is missing from the project ({})", stage, v.name, v.photo.string()));
  }
  cv::Mat bgr = cv::imread(v.photo.string(), cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
  if (bgr.empty()) throw IoError(fmt::format("{}: photo {}: {}: cannot read the photo", stage, v.name, v.photo.string()));
  if (bgr.cols != K.width || bgr.rows != K.height) {
    throw InputError(fmt::format("{}: {}: photo is {} x {} px but its camera is {} x {}", stage, v.photo.string(),
                                 bgr.cols, bgr.rows, K.width, K.height));
  }
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  p.levels.push_back(rgb);
  return p;
}

Projector::Projector(const Camera& c) : cam(c) {
  const Intrinsics& K = c.intrinsics;
  for (const auto& px : {Eigen::Vector2d(0, 0), Eigen::Vector2d(K.width - 1, 0), Eigen::Vector2d(0, K.height - 1),
                         Eigen::Vector2d(K.width - 1, K.height - 1)}) {
    max_r2 = std::max(max_r2, K.to_normalised(px).squaredNorm());
  }
  max_r2 *= 1.44;  // 20 % radial margin
}

bool Projector::project(const Eigen::Vector3d& X, Eigen::Vector2d& px, double& depth) const {
  const Eigen::Vector3d Xc = cam.pose.to_camera(X);
  if (Xc.z() <= 1e-6) return false;
  const Eigen::Vector2d xn = Xc.head<2>() / Xc.z();
  if (xn.squaredNorm() > max_r2) return false;
  px = cam.intrinsics.to_pixel(xn);
  depth = Xc.z();
  return true;
}

DepthBuffer::DepthBuffer(const Intrinsics& K, double scale, bool keep_faces)
    : width_(std::max(1, int(std::ceil(K.width * scale)))),
      height_(std::max(1, int(std::ceil(K.height * scale)))),
      scale_(scale),
      fx_(K.fx),
      depth_(std::size_t(width_) * height_, kNoDepth),
      faces_(keep_faces ? std::size_t(width_) * height_ : 0, kNoFace) {}

void DepthBuffer::draw_triangle(const Eigen::Vector2d& pa, const Eigen::Vector2d& pb, const Eigen::Vector2d& pc,
                                double da, double db, double dc, int face) {
  const double ax = to_buffer(pa.x()), ay = to_buffer(pa.y());
  const double bx = to_buffer(pb.x()), by = to_buffer(pb.y());
  const double cx = to_buffer(pc.x()), cy = to_buffer(pc.y());
  const double area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
  if (std::abs(area) < 1e-12) return;
  const int x0 = std::max(0, int(std::ceil(std::min({ax, bx, cx}))));
  const int x1 = std::min(width_ - 1, int(std::floor(std::max({ax, bx, cx}))));
  const int y0 = std::max(0, int(std::ceil(std::min({ay, by, cy}))));
  const int y1 = std::min(height_ - 1, int(std::floor(std::max({ay, by, cy}))));
  if (x0 > x1 || y0 > y1) return;
  const double ia = 1.0 / da, ib = 1.0 / db, ic = 1.0 / dc;
  constexpr double eps = -1e-9;
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const double wa = ((bx - x) * (cy - y) - (by - y) * (cx - x)) / area;
      const double wb = ((cx - x) * (ay - y) - (cy - y) * (ax - x)) / area;
      const double wc = 1.0 - wa - wb;
      if (wa < eps || wb < eps || wc < eps) continue;
      const float z = float(1.0 / (wa * ia + wb * ib + wc * ic));
      const std::size_t i = std::size_t(y) * width_ + x;
      if (z >= depth_[i]) continue;
      depth_[i] = z;
      if (!faces_.empty()) faces_[i] = face;
    }
  }
}

float DepthBuffer::at(double x, double y) const {
  const int bx = std::clamp(int(std::lround(to_buffer(x))), 0, width_ - 1);
  const int by = std::clamp(int(std::lround(to_buffer(y))), 0, height_ - 1);
  return depth_[std::size_t(by) * width_ + bx];
}

ProjectedVertices project_vertices(const DenseMesh& m, const Projector& proj) {
  ProjectedVertices v;
  v.px.resize(m.vertices.size());
  v.depth.assign(m.vertices.size(), -1);
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    if (!proj.project(m.vertices[i], v.px[i], v.depth[i])) v.depth[i] = -1;
  }
  return v;
}

DepthBuffer mesh_depth_buffer(const DenseMesh& m, const ProjectedVertices& v, const Intrinsics& K, double scale,
                              bool keep_faces) {
  DepthBuffer zbuf(K, scale, keep_faces);
  for (std::size_t fi = 0; fi < m.faces.size(); ++fi) {
    const auto& f = m.faces[fi];
    if (!v.in_view(f)) continue;
    const std::size_t a = std::size_t(f[0]), b = std::size_t(f[1]), c = std::size_t(f[2]);
    zbuf.draw_triangle(v.px[a], v.px[b], v.px[c], v.depth[a], v.depth[b], v.depth[c], int(fi));
  }
  return zbuf;
}

}  // namespace strata
