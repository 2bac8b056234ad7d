#include "products/model_check.hpp"

#include "core/error.hpp"
#include "core/resources.hpp"
#include "core/statistics.hpp"
#include "geometry/polygon.hpp"
#include "products/photo_sampling.hpp"

#include <Eigen/Geometry>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace strata {

void ModelCheckOptions::validate() const {
  auto fail = [](const char* field, const std::string& why) {
    throw InputError(fmt::format("products.model_check: {} {}", field, why));
  };
  if (!(scale > 0 && scale <= 1)) fail("scale", fmt::format("= {} must be in (0, 1]", scale));
  if (!(border_px >= 0)) fail("border_px", fmt::format("= {} must be >= 0", border_px));
  if (!region.empty() && region.size() < 3) fail("region", fmt::format("has {} corners, needs at least 3", region.size()));
  if (!(difference_gain >= 1)) fail("difference_gain", fmt::format("= {} must be >= 1", difference_gain));
}

namespace {

// The per-pixel |difference| of one set of pixels, integer grey levels.
struct DifferenceSample {
  std::array<std::vector<std::uint8_t>, 3> channel;
  std::vector<std::uint16_t> sum;  // of the three channels, 0-765

  void add(const std::uint8_t d[3]) {
    for (int k = 0; k < 3; ++k) channel[std::size_t(k)].push_back(d[k]);
    sum.push_back(std::uint16_t(d[0] + d[1] + d[2]));
  }
  void append(const DifferenceSample& o) {
    for (int k = 0; k < 3; ++k) {
      auto& c = channel[std::size_t(k)];
      c.insert(c.end(), o.channel[std::size_t(k)].begin(), o.channel[std::size_t(k)].end());
    }
    sum.insert(sum.end(), o.sum.begin(), o.sum.end());
  }
};

// percentile()'s rank rule, round(q (n - 1)), in place on samples too large to copy
// as doubles (millions of pixels per photo).
template <class T>
double quantile(std::vector<T>& v, double q) {
  return double(kth_smallest(v, std::size_t(std::lround(q * double(v.size() - 1)))));
}

ColourDifference summarise(DifferenceSample s) {
  ColourDifference out;
  out.pixels = s.sum.size();
  if (out.pixels == 0) {
    const double nan = std::nan("");
    out.median.fill(nan);
    out.p90.fill(nan);
    out.median_mean = out.p90_mean = nan;
    return out;
  }
  for (std::size_t k = 0; k < 3; ++k) {
    out.median[k] = quantile(s.channel[k], 0.5);
    out.p90[k] = quantile(s.channel[k], 0.9);
  }
  out.median_mean = quantile(s.sum, 0.5) / 3.0;
  out.p90_mean = quantile(s.sum, 0.9) / 3.0;
  return out;
}

// The atlas at glTF UV (u, v), bilinear between texel centres ((i + 0.5) / size),
// clamped to the edge as the exported sampler is.
void sample_atlas(const TextureImage& im, const Eigen::Vector2d& uv, std::uint8_t out[3]) {
  const double x = std::clamp(uv.x() * im.width - 0.5, 0.0, double(im.width - 1));
  const double y = std::clamp(uv.y() * im.height - 0.5, 0.0, double(im.height - 1));
  const int x0 = std::min(int(x), im.width - 1), y0 = std::min(int(y), im.height - 1);
  const int x1 = std::min(x0 + 1, im.width - 1), y1 = std::min(y0 + 1, im.height - 1);
  const double ax = x - x0, ay = y - y0;
  auto at = [&](int xx, int yy, int k) { return double(im.rgb[(std::size_t(yy) * im.width + xx) * 3 + k]); };
  for (int k = 0; k < 3; ++k) {
    const double c = (1 - ay) * ((1 - ax) * at(x0, y0, k) + ax * at(x1, y0, k)) +
                     ay * ((1 - ax) * at(x0, y1, k) + ax * at(x1, y1, k));
    out[k] = std::uint8_t(std::clamp(std::lround(c), 0L, 255L));
  }
}

// Barycentric coordinates of the point where the ray (C, d) meets face f's plane;
// false when the ray runs along the plane. Clamped into the face: a pixel centre
// the z-buffer gave to f may lie a hair outside it (the buffer joins the projected
// corners with straight edges, the lens bends them).
bool ray_barycentric(const DenseMesh& m, const std::array<int, 3>& f, const Eigen::Vector3d& C, const Eigen::Vector3d& d,
                     Eigen::Vector3d& w, Eigen::Vector3d& X) {
  const Eigen::Vector3d& a = m.vertices[std::size_t(f[0])];
  const Eigen::Vector3d& b = m.vertices[std::size_t(f[1])];
  const Eigen::Vector3d& c = m.vertices[std::size_t(f[2])];
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double nd = n.dot(d), nn = n.squaredNorm();
  if (std::abs(nd) < 1e-12 * std::sqrt(nn) || nn <= 0) return false;
  X = C + (n.dot(a - C) / nd) * d;
  w.x() = n.dot((b - X).cross(c - X)) / nn;
  w.y() = n.dot((c - X).cross(a - X)) / nn;
  w.z() = 1.0 - w.x() - w.y();
  w = w.cwiseMax(0.0);
  w /= w.sum();
  return true;
}

TextureImage black_image(int w, int h) { return TextureImage{w, h, std::vector<std::uint8_t>(std::size_t(w) * h * 3, 0)}; }

struct PhotoSamples {
  DifferenceSample all, inside, own;

  void append(const PhotoSamples& o) {
    all.append(o.all);
    inside.append(o.inside);
    own.append(o.own);
  }
};

// Renders the model from one view and compares it with its photo (see the header).
PhotoCheck check_photo(const TexturedMesh& model, const OrthoView& view, int view_index, const ModelCheckOptions& o,
                       PhotoSamples& samples) {
  const Stopwatch clock;
  PhotoCheck out;
  out.view = view.name;
  const Camera& cam = view.camera;
  const Intrinsics& K = cam.intrinsics;
  const PhotoPixels photo = load_photo(view, "products.model_check");
  const std::array<double, 3>* gain =
      std::size_t(view_index) < model.view_gains.size() ? &model.view_gains[std::size_t(view_index)] : nullptr;
  const DepthBuffer zbuf =
      mesh_depth_buffer(model.mesh, project_vertices(model.mesh, Projector(cam)), K, o.scale, true);
  const int W = zbuf.width(), H = zbuf.height();
  if (o.images) out.rendered = out.difference = black_image(W, H);
  const Eigen::Vector3d C = cam.pose.centre();
  for (int by = 0; by < H; ++by) {
    for (int bx = 0; bx < W; ++bx) {
      const int f = zbuf.face(bx, by);
      if (f == DepthBuffer::kNoFace) continue;
      const Eigen::Vector2d p(zbuf.to_photo(bx), zbuf.to_photo(by));
      if (p.x() < o.border_px || p.y() < o.border_px || p.x() > K.width - 1 - o.border_px ||
          p.y() > K.height - 1 - o.border_px)
        continue;
      const auto& face = model.mesh.faces[std::size_t(f)];
      Eigen::Vector3d w, X;
      if (!ray_barycentric(model.mesh, face, C, cam.ray(p), w, X)) continue;
      const Eigen::Vector2d uv = (w.x() * model.uv[std::size_t(face[0])].cast<double>() +
                                  w.y() * model.uv[std::size_t(face[1])].cast<double>() +
                                  w.z() * model.uv[std::size_t(face[2])].cast<double>());
      std::uint8_t render[3], truth[3], diff[3];
      sample_atlas(model.atlases[std::size_t(model.face_atlas[std::size_t(f)])], uv, render);
      const std::size_t i = (std::size_t(by) * W + bx) * 3;
      if (o.images) std::copy(render, render + 3, &out.rendered.rgb[i]);
      if (model.face_view[std::size_t(f)] < 0) {
        ++out.untextured_pixels;
        continue;
      }
      photo.sample(p.x(), p.y(), 1.0, truth);  // the pixel itself at scale 1, bilinear between pixels below
      // The photo as the texture shows it: with the gains its texels carry, so that the
      // figures measure resampling and registration, not the levelling between photos.
      if (gain) {
        for (int k = 0; k < 3; ++k) truth[k] = std::uint8_t(std::clamp(std::lround(truth[k] * (*gain)[std::size_t(k)]), 0L, 255L));
      }
      for (int k = 0; k < 3; ++k) diff[k] = std::uint8_t(std::abs(int(render[k]) - int(truth[k])));
      if (o.images) {
        for (int k = 0; k < 3; ++k)
          out.difference.rgb[i + std::size_t(k)] = std::uint8_t(std::min(255.0, std::round(diff[k] * o.difference_gain)));
      }
      samples.all.add(diff);
      if (o.region.empty() || inside_polygon(o.region, X.x(), X.y())) samples.inside.add(diff);
      if (model.face_view[std::size_t(f)] == view_index) samples.own.add(diff);
    }
  }
  out.all = summarise(samples.all);
  out.inside = summarise(samples.inside);
  out.own = summarise(samples.own);
  out.seconds = clock.seconds();
  return out;
}

}  // namespace

ModelCheckSummary check_textured_model(const TexturedMesh& model, const std::vector<OrthoView>& views,
                                       const std::vector<int>& checked, const ModelCheckOptions& options) {
  options.validate();
  STRATA_CHECK(model.uv.size() == model.mesh.vertices.size() && model.face_atlas.size() == model.mesh.faces.size() &&
                   model.face_view.size() == model.mesh.faces.size(),
               "textured mesh with mismatched UVs or face tables");
  const Stopwatch clock;
  ModelCheckSummary out;
  PhotoSamples pooled;
  for (const int v : checked) {
    if (v < 0 || std::size_t(v) >= views.size())
      throw InputError(fmt::format("products.model_check: photo index {} is not one of the {} views", v, views.size()));
    PhotoSamples s;
    out.photos.push_back(check_photo(model, views[std::size_t(v)], v, options, s));
    pooled.append(s);
  }
  out.all = summarise(std::move(pooled.all));
  out.inside = summarise(std::move(pooled.inside));
  out.own = summarise(std::move(pooled.own));
  out.seconds = clock.seconds();
  return out;
}

}  // namespace strata
