#include "products/orthophoto.hpp"

#include "core/parallel.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "core/resources.hpp"
#include "core/statistics.hpp"
#include "products/colour_gains.hpp"
#include "products/photo_sampling.hpp"

#include <Eigen/Dense>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <limits>
#include <mutex>

namespace strata {

void OrthoOptions::validate() const {
  auto bad = [](const char* field, double v, const char* range) {
    throw InputError(fmt::format("products.ortho: {} must be {}, got {}", field, range, v));
  };
  if (!(depth_buffer_scale >= 0 && depth_buffer_scale <= 1)) bad("depth_buffer_scale", depth_buffer_scale, "in [0, 1] (0 = automatic)");
  if (!(depth_tolerance_m >= 0)) bad("depth_tolerance_m", depth_tolerance_m, ">= 0 metres");
  if (!(max_view_angle_deg > 0 && max_view_angle_deg < 90)) bad("max_view_angle_deg", max_view_angle_deg, "in (0, 90) degrees");
  if (!(border_px >= 0)) bad("border_px", border_px, ">= 0 pixels");
  if (candidates < 1 || candidates > 16) bad("candidates", candidates, "in [1, 16]");
  if (!(smoothness >= 0)) bad("smoothness", smoothness, ">= 0");
  if (smoothing_iterations < 0) bad("smoothing_iterations", smoothing_iterations, ">= 0");
  if (!(feather_m >= 0)) bad("feather_m", feather_m, ">= 0 metres");
  if (!(normal_radius_m >= 0)) bad("normal_radius_m", normal_radius_m, ">= 0 metres");
  if (!(rectify_median_radius_m >= 0 && rectify_median_radius_m <= 0.5)) {
    bad("rectify_median_radius_m", rectify_median_radius_m, "in [0, 0.5] metres");
  }
  if (threads < 1) bad("threads", threads, ">= 1");
}

namespace {

constexpr float kNoDepth = DepthBuffer::kNoDepth;

struct ViewSample {
  std::uint32_t cell;
  float score;
  float pixel_m;  // ground size of a photo pixel along the slope seen from this view, metres
  std::uint8_t rgb[3];
};

// Everything one photo contributes: the cells it sees, with score and colour.
std::vector<ViewSample> sample_view(const Dtm& dtm, const std::vector<Eigen::Vector3f>& normals,
                                    const OrthoView& view, const OrthoOptions& o) {
  const RasterGrid& g = dtm.grid;
  const Intrinsics& K = view.camera.intrinsics;
  const Projector proj(view.camera);
  const Eigen::Vector3d C = view.camera.pose.centre();

  // Project every valid cell centre once: used by the z-buffer and the lookup.
  std::vector<float> px(g.cells() * 2, std::numeric_limits<float>::quiet_NaN());
  std::vector<float> depth(g.cells(), kNoDepth);
  std::vector<double> depths;
  for (int r = 0; r < g.height; ++r) {
    for (int c = 0; c < g.width; ++c) {
      const std::size_t i = g.index(c, r);
      if (!std::isfinite(dtm.z[i])) continue;
      Eigen::Vector2d p;
      double d;
      if (!proj.project({g.x_centre(c), g.y_centre(r), double(dtm.z[i])}, p, d)) continue;
      px[2 * i] = float(p.x());
      px[2 * i + 1] = float(p.y());
      depth[i] = float(d);
      if (p.x() >= 0 && p.y() >= 0 && p.x() <= K.width - 1 && p.y() <= K.height - 1) depths.push_back(d);
    }
  }
  if (depths.empty()) return {};
  const double median_depth = median_in_place(depths);

  // z-buffer resolution: automatic = one buffer pixel per DTM cell at the median
  // depth (finer buys nothing, the DTM has no more detail).
  double s = o.depth_buffer_scale;
  if (s == 0) s = std::clamp(g.cell * K.fx / median_depth, 0.05, 1.0);
  DepthBuffer zbuf(K, s);
  auto raster_triangle = [&](std::size_t a, std::size_t b, std::size_t c) {
    zbuf.draw_triangle({px[2 * a], px[2 * a + 1]}, {px[2 * b], px[2 * b + 1]}, {px[2 * c], px[2 * c + 1]}, depth[a],
                       depth[b], depth[c]);
  };
  for (int r = 0; r + 1 < g.height; ++r) {
    for (int c = 0; c + 1 < g.width; ++c) {
      const std::size_t i00 = g.index(c, r), i10 = g.index(c + 1, r), i01 = g.index(c, r + 1),
                        i11 = g.index(c + 1, r + 1);
      const bool v00 = depth[i00] < kNoDepth, v10 = depth[i10] < kNoDepth, v01 = depth[i01] < kNoDepth,
                 v11 = depth[i11] < kNoDepth;
      if (v00 && v10 && v11) raster_triangle(i00, i10, i11);
      if (v00 && v11 && v01) raster_triangle(i00, i11, i01);
      // Quads with one corner missing still occlude with their remaining triangle.
      if (!v00 && v10 && v11 && v01) raster_triangle(i10, i11, i01);
      if (!v11 && v00 && v10 && v01) raster_triangle(i00, i10, i01);
    }
  }

  const double cos_max = std::cos(o.max_view_angle_deg * M_PI / 180.0);
  const double border_scale = 0.1 * std::min(K.width, K.height);  // pixels over which the score ramps
  PhotoPixels photo = load_photo(view, "products.ortho");
  // Photo pixels one cell covers: its side seen square-on at depth d is
  // cell f / d pixels; tilted by the incidence angle its area grows by 1 / cos.
  auto footprint_px = [&](double d, double cos_t) { return g.cell * K.fx / d / std::sqrt(std::max(cos_t, 0.05)); };
  if (o.antialias) photo.build_pyramid(footprint_px(*std::min_element(depths.begin(), depths.end()), cos_max));
  std::vector<ViewSample> out;
  out.reserve(depths.size());
  for (int r = 0; r < g.height; ++r) {
    for (int c = 0; c < g.width; ++c) {
      const std::size_t i = g.index(c, r);
      if (!(depth[i] < kNoDepth)) continue;
      const double x = px[2 * i], y = px[2 * i + 1];
      const double edge = std::min({x, y, K.width - 1 - x, K.height - 1 - y});
      if (edge < o.border_px) continue;
      const Eigen::Vector3d X(g.x_centre(c), g.y_centre(r), double(dtm.z[i]));
      const double d = depth[i];
      const Eigen::Vector3d v = (C - X).normalized();
      const double cos_t = double(normals[i].cast<double>().dot(v));
      if (cos_t < cos_max) continue;
      // Depth test. The buffer's own uncertainty grows with its pixel footprint
      // (d / (f s), metres) and with the slope seen along the ray (tan of the angle).
      const double footprint = zbuf.footprint_m(d);
      const double tan_t = std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t)) / std::max(cos_t, 1e-3);
      const double tol = o.depth_tolerance_m + footprint * (1.0 + std::min(tan_t, 4.0));
      if (d > double(zbuf.at(x, y)) + tol) continue;
      // Photo pixels per metre of surface, lowered to half towards the border
      // (vignetting, residual distortion).
      const double border_w = 0.5 + 0.5 * std::min(1.0, edge / border_scale);
      ViewSample sm;
      sm.cell = std::uint32_t(i);
      sm.score = float(cos_t * K.fx / d * border_w);
      sm.pixel_m = float(d / (K.fx * cos_t));
      photo.sample(x, y, o.antialias ? footprint_px(d, cos_t) : 1.0, sm.rgb);
      out.push_back(sm);
    }
  }
  return out;
}

// Best `k` views of every cell, best first.
struct Candidates {
  int k = 0;
  std::vector<std::int16_t> view;  // -1 = empty slot
  std::vector<float> score;
  std::vector<float> pixel_m;
  std::vector<std::uint8_t> rgb;

  Candidates(std::size_t cells, int k_)
      : k(k_), view(cells * k_, -1), score(cells * k_, 0.f), pixel_m(cells * k_, 0.f), rgb(cells * k_ * 3, 0) {}

  void insert(std::size_t cell, int v, float s, float px_m, const std::uint8_t c[3]) {
    const std::size_t base = cell * k;
    int pos = k;
    while (pos > 0 && (view[base + pos - 1] < 0 || score[base + pos - 1] < s)) --pos;
    if (pos >= k) return;
    for (int j = k - 1; j > pos; --j) {
      view[base + j] = view[base + j - 1];
      score[base + j] = score[base + j - 1];
      pixel_m[base + j] = pixel_m[base + j - 1];
      std::copy_n(&rgb[(base + j - 1) * 3], 3, &rgb[(base + j) * 3]);
    }
    view[base + pos] = std::int16_t(v);
    score[base + pos] = s;
    pixel_m[base + pos] = px_m;
    std::copy_n(c, 3, &rgb[(base + pos) * 3]);
  }
};

// Per-photo, per-channel gains fitted over every pair of candidate views of a cell
// (fit_colour_gains, shared with the texture atlas).
void balance_gains(const Candidates& cand, int n_views, OrthoSummary& s, std::vector<std::array<double, 3>>& gains) {
  ColourOverlaps overlaps;
  const std::size_t cells = cand.view.size() / cand.k;
  for (std::size_t i = 0; i < cells; ++i) {
    const std::size_t base = i * cand.k;
    for (int p = 0; p < cand.k; ++p) {
      const int a = cand.view[base + p];
      if (a < 0) break;
      for (int q = p + 1; q < cand.k; ++q) {
        const int b = cand.view[base + q];
        if (b < 0) break;
        overlaps.add(a, &cand.rgb[(base + p) * 3], b, &cand.rgb[(base + q) * 3]);
      }
    }
  }
  const ColourGains fit = fit_colour_gains(overlaps, n_views);
  gains = fit.gains;
  s.balance_rms_before = fit.rms_before;
  s.balance_rms_after = fit.rms_after;
}

// Separable box filter of radius r over a w x h float image, in place.
void box_blur(std::vector<float>& img, int w, int h, int r) {
  if (r <= 0) return;
  std::vector<float> line(std::size_t(std::max(w, h)));
  const float inv = 1.0f / float(2 * r + 1);
  for (int y = 0; y < h; ++y) {
    float* row = &img[std::size_t(y) * w];
    double acc = 0;
    for (int x = -r; x <= r; ++x) acc += (x >= 0 && x < w) ? row[x] : 0.f;
    for (int x = 0; x < w; ++x) {
      line[std::size_t(x)] = float(acc) * inv;
      const int add = x + r + 1, sub = x - r;
      if (add < w) acc += row[add];
      if (sub >= 0) acc -= row[sub];
    }
    std::copy_n(line.begin(), w, row);
  }
  for (int x = 0; x < w; ++x) {
    double acc = 0;
    for (int y = -r; y <= r; ++y) acc += (y >= 0 && y < h) ? img[std::size_t(y) * w + x] : 0.f;
    for (int y = 0; y < h; ++y) {
      line[std::size_t(y)] = float(acc) * inv;
      const int add = y + r + 1, sub = y - r;
      if (add < h) acc += img[std::size_t(add) * w + x];
      if (sub >= 0) acc -= img[std::size_t(sub) * w + x];
    }
    for (int y = 0; y < h; ++y) img[std::size_t(y) * w + x] = line[std::size_t(y)];
  }
}

// The DTM smoothed by a tent of half-width about `radius_m` (two box filters),
// weighted by validity so that holes do not pull heights; cells without a
// height stay NaN. Used only for the normals.
Dtm smoothed_for_normals(const Dtm& dtm, double radius_m) {
  const RasterGrid& g = dtm.grid;
  const int r = std::max(0, int(std::lround(radius_m / g.cell / 2.0)));
  if (r == 0) return dtm;
  std::vector<float> sum(g.cells(), 0.f), weight(g.cells(), 0.f);
  // Heights relative to a reference keep the float sums precise.
  double ref = 0;
  for (float z : dtm.z)
    if (std::isfinite(z)) {
      ref = z;
      break;
    }
  for (std::size_t i = 0; i < g.cells(); ++i) {
    if (!std::isfinite(dtm.z[i])) continue;
    sum[i] = float(double(dtm.z[i]) - ref);
    weight[i] = 1.f;
  }
  for (int pass = 0; pass < 2; ++pass) {
    box_blur(sum, g.width, g.height, r);
    box_blur(weight, g.width, g.height, r);
  }
  Dtm out = dtm;
  for (std::size_t i = 0; i < g.cells(); ++i) {
    if (std::isfinite(dtm.z[i]) && weight[i] > 1e-6f) out.z[i] = float(double(sum[i] / weight[i]) + ref);
  }
  return out;
}

// The DTM with every height replaced by the median of the valid heights within
// `radius` cells (a square window); holes stay holes. Used to rectify: the fused
// surface's centimetre noise and small floaters, seen from an oblique photo,
// would otherwise shift neighbouring cells by different amounts and warp straight
// edges (a target's code cells), while a median keeps real steps (stones, sides).
Dtm median_heights(const Dtm& dtm, int radius) {
  if (radius <= 0) return dtm;
  const RasterGrid& g = dtm.grid;
  Dtm out = dtm;
  std::vector<float> window;
  window.reserve(std::size_t(2 * radius + 1) * (2 * radius + 1));
  for (int r = 0; r < g.height; ++r) {
    for (int c = 0; c < g.width; ++c) {
      if (!std::isfinite(dtm.z[g.index(c, r)])) continue;
      window.clear();
      for (int rr = std::max(0, r - radius); rr <= std::min(g.height - 1, r + radius); ++rr) {
        for (int cc = std::max(0, c - radius); cc <= std::min(g.width - 1, c + radius); ++cc) {
          const float z = dtm.z[g.index(cc, rr)];
          if (std::isfinite(z)) window.push_back(z);
        }
      }
      out.z[g.index(c, r)] = median_in_place(window);
    }
  }
  return out;
}


// Visibility, scores and colours of every view, one photo per worker at a time.
void collect_candidates(const Dtm& rect, const std::vector<Eigen::Vector3f>& normals, const std::vector<OrthoView>& views,
                        const OrthoOptions& o, Candidates& cand) {
  Progress progress("orthophoto: views", views.size());
  std::mutex merge;
  parallel_for_index(views.size(), o.threads, [&](std::size_t v) {
    check_cancelled();
    const std::vector<ViewSample> samples = sample_view(rect, normals, views[v], o);
    const std::lock_guard<std::mutex> lock(merge);
    for (const ViewSample& sm : samples) cand.insert(sm.cell, int(v), sm.score, sm.pixel_m, sm.rgb);
    progress.step();
  });
  progress.finish();
}

// Radiometric balance: per-view gains fitted over the overlaps, applied to every
// candidate colour.
void balance_colours(Candidates& cand, std::size_t cells, int views, const OrthoOptions& o, OrthoSummary& s) {
  std::vector<std::array<double, 3>> gains(std::size_t(views), {1.0, 1.0, 1.0});
  if (o.radiometric_balance && views > 1) balance_gains(cand, views, s, gains);
  for (std::size_t i = 0; i < cells; ++i) {
    for (int p = 0; p < cand.k; ++p) {
      const int v = cand.view[i * cand.k + p];
      if (v < 0) break;
      std::uint8_t* c = &cand.rgb[(i * cand.k + p) * 3];
      for (int ch = 0; ch < 3; ++ch) {
        c[ch] = std::uint8_t(std::clamp(std::lround(c[ch] * gains[std::size_t(v)][std::size_t(ch)]), 0L, 255L));
      }
    }
  }
  s.gains = gains;
}

// Region labels (view index per cell, -1 unseen): best score, then ICM on
// score/best + smoothness * agreeing 4-neighbours / 4 (a Potts prior, solved
// greedily; Besag 1986).
std::vector<std::int16_t> region_labels(const Candidates& cand, const RasterGrid& g, const OrthoOptions& o) {
  std::vector<std::int16_t> label(g.cells(), -1);
  for (std::size_t i = 0; i < g.cells(); ++i) label[i] = cand.view[i * cand.k];
  for (int it = 0; it < o.smoothing_iterations && o.smoothness > 0; ++it) {
    std::size_t changed = 0;
    for (int r = 0; r < g.height; ++r) {
      for (int c = 0; c < g.width; ++c) {
        const std::size_t i = g.index(c, r);
        if (label[i] < 0) continue;
        const std::size_t base = i * cand.k;
        const float best = cand.score[base];
        std::int16_t nb[4] = {-1, -1, -1, -1};
        if (c > 0) nb[0] = label[i - 1];
        if (c + 1 < g.width) nb[1] = label[i + 1];
        if (r > 0) nb[2] = label[i - g.width];
        if (r + 1 < g.height) nb[3] = label[i + g.width];
        double best_e = -1;
        std::int16_t best_v = label[i];
        for (int p = 0; p < cand.k; ++p) {
          const std::int16_t v = cand.view[base + p];
          if (v < 0) break;
          int agree = 0;
          for (std::int16_t n : nb) agree += (n == v) ? 1 : 0;
          const double e = double(cand.score[base + p]) / double(best) + o.smoothness * agree / 4.0;
          if (e > best_e + 1e-12) {
            best_e = e;
            best_v = v;
          }
        }
        if (best_v != label[i]) {
          label[i] = best_v;
          ++changed;
        }
      }
    }
    if (changed == 0) break;
  }
  return label;
}

// Colour sums of the feathered blend and their weights per cell.
struct Blend {
  std::vector<float> acc;   // 3 per cell
  std::vector<float> wsum;  // 1 per cell
};

// One view's region mask, box-filtered twice (a tent of half-width about
// feather_m), weights the candidates that view provides.
void blend_view(std::size_t v, const Candidates& cand, const std::vector<std::int16_t>& label, const RasterGrid& g,
                int radius, Blend& b) {
  int c0 = g.width, c1 = -1, r0 = g.height, r1 = -1;
  for (int r = 0; r < g.height; ++r) {
    for (int c = 0; c < g.width; ++c) {
      if (label[g.index(c, r)] != std::int16_t(v)) continue;
      c0 = std::min(c0, c);
      c1 = std::max(c1, c);
      r0 = std::min(r0, r);
      r1 = std::max(r1, r);
    }
  }
  c0 = std::max(0, c0 - 2 * radius);
  r0 = std::max(0, r0 - 2 * radius);
  c1 = std::min(g.width - 1, c1 + 2 * radius);
  r1 = std::min(g.height - 1, r1 + 2 * radius);
  const int w = c1 - c0 + 1, h = r1 - r0 + 1;
  std::vector<float> mask(std::size_t(w) * h, 0.f);
  for (int r = r0; r <= r1; ++r) {
    for (int c = c0; c <= c1; ++c) {
      mask[std::size_t(r - r0) * w + (c - c0)] = label[g.index(c, r)] == std::int16_t(v) ? 1.f : 0.f;
    }
  }
  box_blur(mask, w, h, radius);
  box_blur(mask, w, h, radius);
  for (int r = r0; r <= r1; ++r) {
    for (int c = c0; c <= c1; ++c) {
      const float wt = mask[std::size_t(r - r0) * w + (c - c0)];
      if (wt <= 1e-6f) continue;
      const std::size_t i = g.index(c, r);
      if (label[i] < 0) continue;
      for (int p = 0; p < cand.k; ++p) {
        const int cv = cand.view[i * cand.k + p];
        if (cv < 0) break;
        if (cv != int(v)) continue;
        const std::uint8_t* col = &cand.rgb[(i * cand.k + p) * 3];
        for (int ch = 0; ch < 3; ++ch) b.acc[i * 3 + ch] += wt * col[ch];
        b.wsum[i] += wt;
        break;
      }
    }
  }
}

Blend feathered_blend(const Candidates& cand, const std::vector<std::int16_t>& label, const RasterGrid& g,
                      std::size_t views, const OrthoOptions& o, OrthoSummary& s) {
  const int radius = std::max(0, int(std::lround(o.feather_m / g.cell / 2.0)));
  Blend b{std::vector<float>(g.cells() * 3, 0.f), std::vector<float>(g.cells(), 0.f)};
  s.cells_per_view.assign(views, 0);
  for (std::size_t i = 0; i < g.cells(); ++i) {
    if (label[i] >= 0) ++s.cells_per_view[std::size_t(label[i])];
  }
  for (std::size_t v = 0; v < views; ++v) {
    if (s.cells_per_view[v] == 0) continue;
    ++s.views_used;
    blend_view(v, cand, label, g, radius, b);
  }
  return b;
}

// The image: the blend where it has weight, else the cell's own view's colour;
// counts the coloured cells and the seams between regions.
RgbaRaster compose(const Candidates& cand, const std::vector<std::int16_t>& label, const Blend& b, const RasterGrid& g,
                   OrthoSummary& s, std::size_t& seams) {
  const std::vector<float>& acc = b.acc;
  const std::vector<float>& wsum = b.wsum;
  RgbaRaster out;
  out.grid = g;
  out.rgba.assign(g.cells() * 4, 0);
  s.source_pixel_m.assign(g.cells(), std::numeric_limits<float>::quiet_NaN());
  for (int r = 0; r < g.height; ++r) {
    for (int c = 0; c < g.width; ++c) {
      const std::size_t i = g.index(c, r);
      if (label[i] < 0) continue;
      const std::uint8_t* own = &cand.rgb[(i * cand.k) * 3];
      s.source_pixel_m[i] = cand.pixel_m[i * cand.k];
      for (int p = 0; p < cand.k; ++p) {
        if (cand.view[i * cand.k + p] == label[i]) {
          own = &cand.rgb[(i * cand.k + p) * 3];
          s.source_pixel_m[i] = cand.pixel_m[i * cand.k + p];
          break;
        }
      }
      for (int ch = 0; ch < 3; ++ch) {
        const float v = wsum[i] > 0 ? acc[i * 3 + ch] / wsum[i] : float(own[ch]);
        out.rgba[i * 4 + ch] = std::uint8_t(std::clamp(std::lround(v), 0L, 255L));
      }
      out.rgba[i * 4 + 3] = 255;
      ++s.coloured_cells;
      const bool seam = (c + 1 < g.width && label[i + 1] >= 0 && label[i + 1] != label[i]) ||
                        (r + 1 < g.height && label[i + g.width] >= 0 && label[i + g.width] != label[i]);
      seams += seam ? 1 : 0;
    }
  }
  return out;
}

}  // namespace

RgbaRaster build_orthophoto(const Dtm& dtm, const std::vector<OrthoView>& views, const OrthoOptions& o,
                            OrthoSummary* summary_out) {
  o.validate();
  Stopwatch clock;
  const RasterGrid& g = dtm.grid;
  STRATA_CHECK(dtm.z.size() == g.cells(), "DTM size mismatch");
  if (views.size() > 32000) throw InputError("products.ortho: more than 32000 photos in one orthophoto");
  OrthoSummary s;
  s.views = int(views.size());
  for (const auto& v : views) s.view_names.push_back(v.name);
  for (float z : dtm.z) s.dtm_cells += std::isfinite(z) ? 1 : 0;

  const Dtm rect = median_heights(dtm, int(std::lround(o.rectify_median_radius_m / g.cell)));
  const std::vector<Eigen::Vector3f> normals = dtm_normals(smoothed_for_normals(rect, o.normal_radius_m));
  Candidates cand(g.cells(), o.candidates);
  collect_candidates(rect, normals, views, o, cand);
  balance_colours(cand, g.cells(), int(views.size()), o, s);
  const std::vector<std::int16_t> label = region_labels(cand, g, o);
  const Blend blend = feathered_blend(cand, label, g, views.size(), o, s);
  std::size_t seams = 0;
  RgbaRaster out = compose(cand, label, blend, g, s, seams);
  if (s.coloured_cells == 0) {
    throw ProcessingError("products.ortho: no photo sees any DTM cell (check the alignment and the surface)");
  }
  s.coverage = s.dtm_cells ? double(s.coloured_cells) / double(s.dtm_cells) : 0.0;
  s.seam_fraction = double(seams) / double(s.coloured_cells);
  s.seconds = clock.seconds();
  if (summary_out) *summary_out = std::move(s);
  return out;
}

}  // namespace strata
