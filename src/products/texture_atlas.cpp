#include "products/texture_atlas.hpp"

#include "core/error.hpp"
#include "core/resources.hpp"
#include "core/statistics.hpp"
#include "products/colour_gains.hpp"
#include "products/photo_sampling.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <unordered_map>

namespace strata {

void TextureOptions::validate() const {
  auto bad = [](const char* field, double v, const char* range) {
    throw InputError(fmt::format("products.texture: {} must be {}, got {}", field, range, v));
  };
  if (atlas_size_px < 64 || atlas_size_px > 16384) bad("atlas_size_px", atlas_size_px, "in [64, 16384] texels");
  if (max_atlases < 1) bad("max_atlases", max_atlases, ">= 1");
  if (!(texel_scale > 0 && texel_scale <= 4)) bad("texel_scale", texel_scale, "in (0, 4] texels per photo pixel");
  if (gutter_px < 1 || gutter_px > 64) bad("gutter_px", gutter_px, "in [1, 64] texels");
  if (!(max_view_angle_deg > 0 && max_view_angle_deg < 90)) bad("max_view_angle_deg", max_view_angle_deg, "in (0, 90) degrees");
  if (!(depth_buffer_scale > 0 && depth_buffer_scale <= 1)) bad("depth_buffer_scale", depth_buffer_scale, "in (0, 1]");
  if (!(depth_tolerance_m >= 0)) bad("depth_tolerance_m", depth_tolerance_m, ">= 0 metres");
  if (!(border_px >= 0)) bad("border_px", border_px, ">= 0 pixels");
  if (candidates < 1 || candidates > 16) bad("candidates", candidates, "in [1, 16]");
  if (!(smoothness >= 0)) bad("smoothness", smoothness, ">= 0");
  if (smoothing_iterations < 0) bad("smoothing_iterations", smoothing_iterations, ">= 0");
}

namespace {

constexpr int kNoView = -1;
constexpr int kGreyPatchPx = 8;  // texels, side of the patch untextured faces use

struct FaceGeometry {
  std::vector<Eigen::Vector3d> normal;  // unit; zero for a degenerate face
  std::vector<std::array<int, 3>> neighbours;  // across edge k (vertices k, k+1); -1: border or non-manifold
};

FaceGeometry face_geometry(const DenseMesh& m) {
  FaceGeometry g;
  g.normal.resize(m.faces.size());
  g.neighbours.assign(m.faces.size(), {-1, -1, -1});
  std::unordered_map<std::uint64_t, std::vector<std::pair<int, int>>> edges;  // edge -> (face, k)
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    const auto& v = m.faces[f];
    const Eigen::Vector3d n = (m.vertices[v[1]] - m.vertices[v[0]]).cross(m.vertices[v[2]] - m.vertices[v[0]]);
    g.normal[f] = n.norm() > 0 ? Eigen::Vector3d(n.normalized()) : Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = std::uint32_t(v[k]), b = std::uint32_t(v[(k + 1) % 3]);
      edges[(std::uint64_t(std::min(a, b)) << 32) | std::max(a, b)].push_back({int(f), k});
    }
  }
  for (const auto& [key, fs] : edges) {
    if (fs.size() != 2) continue;
    g.neighbours[std::size_t(fs[0].first)][std::size_t(fs[0].second)] = fs[1].first;
    g.neighbours[std::size_t(fs[1].first)][std::size_t(fs[1].second)] = fs[0].first;
  }
  return g;
}

// Best views of every face, best first, with the face's mean colour in each.
struct FaceCandidates {
  int k = 0;
  std::vector<int> view;  // kNoView = empty slot
  std::vector<float> score;
  std::vector<float> texel_m;     // ground size of one photo pixel on the face, metres
  std::vector<std::uint8_t> rgb;  // 3 per slot: the photo's mean at the face's test points (colour balance only)

  FaceCandidates(std::size_t faces, int k_)
      : k(k_), view(faces * k_, kNoView), score(faces * k_, 0), texel_m(faces * k_, 0), rgb(faces * k_ * 3, 0) {}
  void insert(std::size_t f, int v, float s, float px_m, const std::array<std::uint8_t, 3>& c) {
    const std::size_t base = f * k;
    int pos = k;
    while (pos > 0 && (view[base + pos - 1] == kNoView || score[base + pos - 1] < s)) --pos;
    if (pos >= k) return;
    for (int j = k - 1; j > pos; --j) {
      view[base + j] = view[base + j - 1];
      score[base + j] = score[base + j - 1];
      texel_m[base + j] = texel_m[base + j - 1];
      std::copy_n(&rgb[(base + j - 1) * 3], 3, &rgb[(base + j) * 3]);
    }
    view[base + pos] = v;
    score[base + pos] = s;
    texel_m[base + pos] = px_m;
    std::copy(c.begin(), c.end(), &rgb[(base + pos) * 3]);
  }
};

// Points of a face tested against the z-buffer: the centroid and three points
// towards the corners (corners themselves touch the neighbours that may occlude
// them by a buffer pixel).
constexpr std::array<std::array<double, 3>, 4> kTestPoints = {
    {{1.0 / 3, 1.0 / 3, 1.0 / 3}, {0.7, 0.15, 0.15}, {0.15, 0.7, 0.15}, {0.15, 0.15, 0.7}}};

void score_view(const DenseMesh& m, const FaceGeometry& g, const OrthoView& view, int v, const TextureOptions& o,
                FaceCandidates& cand) {
  const Intrinsics& K = view.camera.intrinsics;
  const Projector proj(view.camera);
  const Eigen::Vector3d C = view.camera.pose.centre();
  const ProjectedVertices projected = project_vertices(m, proj);
  const std::vector<Eigen::Vector2d>& px = projected.px;
  const DepthBuffer zbuf = mesh_depth_buffer(m, projected, K, o.depth_buffer_scale);
  // The photo itself only for the colour balance: a face's colour in each candidate view.
  const PhotoPixels photo = o.colour_balance ? load_photo(view, "products.texture") : PhotoPixels{};
  const double cos_max = std::cos(o.max_view_angle_deg * M_PI / 180.0);
  auto inside = [&](const Eigen::Vector2d& p) {
    return p.x() >= o.border_px && p.y() >= o.border_px && p.x() <= K.width - 1 - o.border_px &&
           p.y() <= K.height - 1 - o.border_px;
  };
  for (std::size_t fi = 0; fi < m.faces.size(); ++fi) {
    const auto& f = m.faces[fi];
    if (!projected.in_view(f)) continue;
    if (!inside(px[f[0]]) || !inside(px[f[1]]) || !inside(px[f[2]])) continue;
    const Eigen::Vector3d X = (m.vertices[f[0]] + m.vertices[f[1]] + m.vertices[f[2]]) / 3.0;
    const double cos_t = g.normal[fi].dot((C - X).normalized());
    if (cos_t < cos_max) continue;
    // Depth test, with the tolerance of the orthophoto: the buffer pixel's own
    // footprint, grown with the slope seen along the ray.
    const double tan_t = std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t)) / std::max(cos_t, 1e-3);
    bool visible = true;
    double d_centre = 0;
    std::array<double, 3> colour_sum = {0, 0, 0};
    for (const auto& w : kTestPoints) {
      const Eigen::Vector3d P = w[0] * m.vertices[f[0]] + w[1] * m.vertices[f[1]] + w[2] * m.vertices[f[2]];
      Eigen::Vector2d p;
      double d;
      if (!proj.project(P, p, d)) {
        visible = false;
        break;
      }
      if (d_centre == 0) d_centre = d;
      const double tol = o.depth_tolerance_m + zbuf.footprint_m(d) * (1.0 + std::min(tan_t, 4.0));
      if (d > double(zbuf.at(p.x(), p.y())) + tol) {
        visible = false;
        break;
      }
      if (o.colour_balance) {
        std::uint8_t c[3];
        photo.sample(p.x(), p.y(), 1.0, c);
        for (int k = 0; k < 3; ++k) colour_sum[std::size_t(k)] += c[k];
      }
    }
    if (!visible) continue;
    std::array<std::uint8_t, 3> colour{};
    for (int k = 0; k < 3; ++k) colour[std::size_t(k)] = std::uint8_t(std::lround(colour_sum[std::size_t(k)] / kTestPoints.size()));
    const Eigen::Vector2d e1 = px[f[1]] - px[f[0]], e2 = px[f[2]] - px[f[0]];
    const double area_px = 0.5 * std::abs(e1.x() * e2.y() - e1.y() * e2.x());
    if (!(area_px > 0)) continue;
    cand.insert(fi, v, float(area_px * cos_t), float(d_centre / (K.fx * cos_t)), colour);
  }
}

// Iterated conditional modes on a Potts model (see the header).
std::vector<int> smooth_labels(const FaceCandidates& cand, const FaceGeometry& g, const TextureOptions& o) {
  const std::size_t faces = g.normal.size();
  std::vector<int> label(faces, kNoView);
  for (std::size_t f = 0; f < faces; ++f) label[f] = cand.view[f * cand.k];
  for (int it = 0; it < o.smoothing_iterations; ++it) {
    std::size_t changed = 0;
    for (std::size_t f = 0; f < faces; ++f) {
      const std::size_t base = f * cand.k;
      if (cand.view[base] == kNoView) continue;
      int n_neighbours = 0;
      for (int nb : g.neighbours[f]) n_neighbours += nb >= 0 ? 1 : 0;
      double best_e = std::numeric_limits<double>::infinity();
      int best = label[f];
      for (int j = 0; j < cand.k && cand.view[base + j] != kNoView; ++j) {
        const int v = cand.view[base + j];
        int differ = 0;
        for (int nb : g.neighbours[f]) differ += (nb >= 0 && label[std::size_t(nb)] != v) ? 1 : 0;
        const double e = 1.0 - double(cand.score[base + j]) / double(cand.score[base]) +
                         o.smoothness * differ / std::max(1, n_neighbours);
        if (e < best_e) {
          best_e = e;
          best = v;
        }
      }
      if (best != label[f]) ++changed;
      label[f] = best;
    }
    if (changed == 0) break;
  }
  return label;
}

// Gains per view and channel from the candidate views of every face several photos
// see: each pair of candidates is one overlap of the orthophoto's solver.
ColourGains face_colour_gains(const FaceCandidates& cand, int n_views) {
  ColourOverlaps overlaps;
  const std::size_t faces = cand.view.size() / std::size_t(cand.k);
  for (std::size_t f = 0; f < faces; ++f) {
    const std::size_t base = f * cand.k;
    for (int p = 0; p < cand.k && cand.view[base + p] != kNoView; ++p) {
      for (int q = p + 1; q < cand.k && cand.view[base + q] != kNoView; ++q) {
        overlaps.add(cand.view[base + p], &cand.rgb[(base + p) * 3], cand.view[base + q], &cand.rgb[(base + q) * 3]);
      }
    }
  }
  return fit_colour_gains(overlaps, n_views);
}

struct Chart {
  int view = kNoView;
  std::vector<int> faces;
  Eigen::Vector2d lo = Eigen::Vector2d::Zero(), hi = Eigen::Vector2d::Zero();  // photo pixels, bounding box of its vertices' projections
  int page = 0, x = 0, y = 0;  // atlas and top-left texel of its rectangle (gutter included)
  int w = 0, h = 0;            // texels, gutter included
};

// Connected faces on one view.
std::vector<Chart> grow_charts(const std::vector<int>& label, const FaceGeometry& g) {
  std::vector<Chart> charts;
  std::vector<char> seen(label.size(), 0);
  std::vector<int> stack;
  for (std::size_t f0 = 0; f0 < label.size(); ++f0) {
    if (seen[f0] || label[f0] == kNoView) continue;
    Chart c;
    c.view = label[f0];
    stack.assign(1, int(f0));
    seen[f0] = 1;
    while (!stack.empty()) {
      const int f = stack.back();
      stack.pop_back();
      c.faces.push_back(f);
      for (int nb : g.neighbours[std::size_t(f)]) {
        if (nb >= 0 && !seen[std::size_t(nb)] && label[std::size_t(nb)] == c.view) {
          seen[std::size_t(nb)] = 1;
          stack.push_back(nb);
        }
      }
    }
    charts.push_back(std::move(c));
  }
  return charts;
}

// Vertex projections of the faces of every chart, per view (photo pixels).
using ChartPixels = std::vector<std::unordered_map<int, Eigen::Vector2d>>;  // per chart: vertex -> pixel

void chart_bounds(Chart& c, const std::unordered_map<int, Eigen::Vector2d>& px) {
  c.lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  c.hi = -c.lo;
  for (const auto& [v, p] : px) {
    c.lo = c.lo.cwiseMin(p);
    c.hi = c.hi.cwiseMax(p);
  }
}

std::unordered_map<int, Eigen::Vector2d> project_chart(const Chart& c, const DenseMesh& m, const Camera& cam) {
  std::unordered_map<int, Eigen::Vector2d> px;
  const Projector proj(cam);
  for (int f : c.faces) {
    for (int v : m.faces[std::size_t(f)]) {
      if (px.count(v)) continue;
      Eigen::Vector2d p;
      double d;
      proj.project(m.vertices[std::size_t(v)], p, d);  // succeeded when the face was scored
      px[v] = p;
    }
  }
  return px;
}

// Splits charts whose rectangle exceeds `max_side` texels at `scale` in halves
// (faces by centroid pixel along the longer side) until all fit.
void split_large(std::vector<Chart>& charts, ChartPixels& pixels, const DenseMesh& m, double scale, int max_side) {
  for (std::size_t i = 0; i < charts.size(); ++i) {
    while (true) {
      const Eigen::Vector2d ext = (charts[i].hi - charts[i].lo) * scale;
      if (std::max(ext.x(), ext.y()) + 2 <= max_side || charts[i].faces.size() < 2) break;
      const int axis = ext.x() >= ext.y() ? 0 : 1;
      auto centre = [&](int f) {
        const auto& v = m.faces[std::size_t(f)];
        return (pixels[i][v[0]][axis] + pixels[i][v[1]][axis] + pixels[i][v[2]][axis]) / 3.0;
      };
      std::vector<int>& fs = charts[i].faces;
      const auto mid = fs.begin() + std::ptrdiff_t(fs.size() / 2);
      std::nth_element(fs.begin(), mid, fs.end(), [&](int a, int b) { return centre(a) < centre(b); });
      Chart other;
      other.view = charts[i].view;
      other.faces.assign(mid, fs.end());
      fs.erase(mid, fs.end());
      auto px_a = std::move(pixels[i]);
      std::unordered_map<int, Eigen::Vector2d> pa, pb;
      for (int f : fs)
        for (int v : m.faces[std::size_t(f)]) pa[v] = px_a[v];
      for (int f : other.faces)
        for (int v : m.faces[std::size_t(f)]) pb[v] = px_a[v];
      chart_bounds(charts[i], pa);
      chart_bounds(other, pb);
      pixels[i] = std::move(pa);
      charts.push_back(std::move(other));
      pixels.push_back(std::move(pb));
    }
  }
}

// Shelf packing, tallest first; returns the number of atlases used. Chart 0 of
// `extra` sizes (the grey patch) goes first.
int pack(std::vector<Chart>& charts, int size, int gutter, double scale) {
  for (Chart& c : charts) {
    if (c.view == kNoView) {
      c.w = c.h = kGreyPatchPx + 2 * gutter;
    } else {
      c.w = int(std::ceil((c.hi.x() - c.lo.x()) * scale)) + 1 + 2 * gutter;
      c.h = int(std::ceil((c.hi.y() - c.lo.y()) * scale)) + 1 + 2 * gutter;
    }
  }
  std::vector<std::size_t> order(charts.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return charts[a].h > charts[b].h; });
  int page = 0, x = 0, y = 0, shelf_h = 0;
  for (std::size_t i : order) {
    Chart& c = charts[i];
    if (x + c.w > size) {
      x = 0;
      y += shelf_h;
      shelf_h = 0;
    }
    if (y + c.h > size) {
      ++page;
      x = y = shelf_h = 0;
    }
    c.page = page;
    c.x = x;
    c.y = y;
    x += c.w;
    shelf_h = std::max(shelf_h, c.h);
  }
  return page + 1;
}

// Texel (column, row) centre of a chart vertex whose photo pixel is p.
Eigen::Vector2d texel_of(const Chart& c, const Eigen::Vector2d& p, int gutter, double scale) {
  return Eigen::Vector2d(c.x + gutter, c.y + gutter) + (p - c.lo) * scale;
}

struct Page {
  TextureImage image;
  std::vector<std::uint8_t> covered;
};

void fill_chart(const Chart& c, const std::unordered_map<int, Eigen::Vector2d>& px, const DenseMesh& m,
                const Camera& cam, const PhotoPixels& photo, const std::array<double, 3>& gain, int gutter,
                double scale, Page& page) {
  const Projector proj(cam);
  const int W = page.image.width;
  const double footprint = 1.0 / scale;  // photo pixels per texel
  for (int f : c.faces) {
    const auto& v = m.faces[std::size_t(f)];
    const Eigen::Vector2d a = texel_of(c, px.at(v[0]), gutter, scale), b = texel_of(c, px.at(v[1]), gutter, scale),
                          d = texel_of(c, px.at(v[2]), gutter, scale);
    const double area = (b.x() - a.x()) * (d.y() - a.y()) - (b.y() - a.y()) * (d.x() - a.x());
    if (std::abs(area) < 1e-12) continue;
    // Texels whose centre lies within half a texel of the triangle: neighbours
    // inside the chart overlap by that much, so no texel between them is left out.
    const int x0 = std::max(c.x, int(std::floor(std::min({a.x(), b.x(), d.x()}) - 0.5)));
    const int x1 = std::min(c.x + c.w - 1, int(std::ceil(std::max({a.x(), b.x(), d.x()}) + 0.5)));
    const int y0 = std::max(c.y, int(std::floor(std::min({a.y(), b.y(), d.y()}) - 0.5)));
    const int y1 = std::min(c.y + c.h - 1, int(std::ceil(std::max({a.y(), b.y(), d.y()}) + 0.5)));
    const double tol_w = 0.75 / std::sqrt(std::abs(area));  // about half a texel in barycentric units
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        double wa = ((b.x() - x) * (d.y() - y) - (b.y() - y) * (d.x() - x)) / area;
        double wb = ((d.x() - x) * (a.y() - y) - (d.y() - y) * (a.x() - x)) / area;
        double wc = 1.0 - wa - wb;
        if (wa < -tol_w || wb < -tol_w || wc < -tol_w) continue;
        const std::size_t t = std::size_t(y) * W + x;
        wa = std::max(wa, 0.0), wb = std::max(wb, 0.0), wc = std::max(wc, 0.0);
        const double s = wa + wb + wc;
        const Eigen::Vector3d X =
            (wa * m.vertices[std::size_t(v[0])] + wb * m.vertices[std::size_t(v[1])] + wc * m.vertices[std::size_t(v[2])]) / s;
        Eigen::Vector2d p;
        double depth;
        if (!proj.project(X, p, depth)) continue;
        std::uint8_t* texel = &page.image.rgb[3 * t];
        photo.sample(p.x(), p.y(), footprint, texel);
        for (int k = 0; k < 3; ++k) {
          texel[k] = std::uint8_t(std::clamp(std::lround(texel[k] * gain[std::size_t(k)]), 0L, 255L));
        }
        page.covered[t] = 1;
      }
    }
  }
}

// Fills `gutter` rings of texels around the covered ones with their covered
// neighbours' mean (a dilation), so that bilinear and mipmapped lookups near a
// chart's edge read the chart's colours, not the empty atlas.
void dilate(Page& page, int gutter) {
  const int W = page.image.width, H = page.image.height;
  std::vector<std::size_t> ring;
  for (int it = 0; it < gutter; ++it) {
    ring.clear();
    for (int y = 0; y < H; ++y) {
      for (int x = 0; x < W; ++x) {
        const std::size_t t = std::size_t(y) * W + x;
        if (page.covered[t]) continue;
        int sum[3] = {0, 0, 0}, n = 0;
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if (xx < 0 || yy < 0 || xx >= W || yy >= H) continue;
            const std::size_t u = std::size_t(yy) * W + xx;
            if (page.covered[u] != 1) continue;
            for (int k = 0; k < 3; ++k) sum[k] += page.image.rgb[3 * u + k];
            ++n;
          }
        }
        if (n == 0) continue;
        for (int k = 0; k < 3; ++k) page.image.rgb[3 * t + k] = std::uint8_t((sum[k] + n / 2) / n);
        ring.push_back(t);
      }
    }
    for (std::size_t t : ring) page.covered[t] = 1;
  }
}


// Shrinks the texel scale until the charts pack into max_atlases; returns the
// number of pages, `scale` the scale they packed at.
int fit_charts(std::vector<Chart>& charts, ChartPixels& pixels, const DenseMesh& m, const TextureOptions& o,
               double& scale) {
  scale = o.texel_scale;
  int pages = 0;
  for (int attempt = 0;; ++attempt) {
    split_large(charts, pixels, m, scale, o.atlas_size_px - 2 * o.gutter_px);
    pages = pack(charts, o.atlas_size_px, o.gutter_px, scale);
    if (pages <= o.max_atlases || attempt > 20) break;
    scale *= 0.9 * std::sqrt(double(o.max_atlases) / pages);
  }
  if (pages > o.max_atlases) {
    throw ProcessingError(fmt::format("products.texture: the charts do not fit in {} atlases of {} px; raise max_atlases",
                                      o.max_atlases, o.atlas_size_px));
  }
  return pages;
}

// The atlas pages: each chart's texels from its photo, then the grey patch of the
// untextured faces (their mean vertex colour, or mid grey), then the gutters.
std::vector<Page> paint_atlases(const std::vector<Chart>& charts, const ChartPixels& pixels, const Chart& grey,
                                const DenseMesh& m, const std::vector<OrthoView>& views,
                                const std::vector<std::array<double, 3>>& gains, const TextureOptions& o, int pages,
                                double scale) {
  std::vector<Page> atlas(static_cast<std::size_t>(pages));
  for (Page& p : atlas) {
    p.image.width = p.image.height = o.atlas_size_px;
    p.image.rgb.assign(std::size_t(o.atlas_size_px) * o.atlas_size_px * 3, 0);
    p.covered.assign(std::size_t(o.atlas_size_px) * o.atlas_size_px, 0);
  }
  // Charts by view, so each photo is read once.
  std::map<int, std::vector<std::size_t>> by_view;
  for (std::size_t i = 0; i < charts.size(); ++i) by_view[charts[i].view].push_back(i);
  for (const auto& [v, idx] : by_view) {
    if (v == kNoView) continue;
    PhotoPixels photo = load_photo(views[std::size_t(v)], "products.texture");
    if (scale < 1) photo.build_pyramid(1.0 / scale);
    for (std::size_t i : idx)
      fill_chart(charts[i], pixels[i], m, views[std::size_t(v)].camera, photo, gains[std::size_t(v)], o.gutter_px,
                 scale, atlas[std::size_t(charts[i].page)]);
  }
  std::array<std::uint8_t, 3> grey_rgb = {128, 128, 128};
  if (!grey.faces.empty() && !m.colours.empty()) {
    std::array<double, 3> sum = {0, 0, 0};
    for (int f : grey.faces)
      for (int v : m.faces[std::size_t(f)])
        for (int k = 0; k < 3; ++k) sum[k] += m.colours[std::size_t(v)][k];
    for (int k = 0; k < 3; ++k) grey_rgb[std::size_t(k)] = std::uint8_t(std::lround(sum[std::size_t(k)] / (3.0 * grey.faces.size())));
  }
  for (const Chart& c : charts) {
    if (c.view != kNoView) continue;
    Page& p = atlas[std::size_t(c.page)];
    for (int y = c.y + o.gutter_px; y < c.y + o.gutter_px + kGreyPatchPx; ++y)
      for (int x = c.x + o.gutter_px; x < c.x + o.gutter_px + kGreyPatchPx; ++x) {
        const std::size_t t = std::size_t(y) * p.image.width + x;
        std::copy(grey_rgb.begin(), grey_rgb.end(), &p.image.rgb[3 * t]);
        p.covered[t] = 1;
      }
  }
  for (Page& p : atlas) dilate(p, o.gutter_px);

  return atlas;
}

// The output mesh: one vertex per (mesh vertex, chart).
TexturedMesh textured_output(const std::vector<Chart>& charts, const ChartPixels& pixels, const DenseMesh& m,
                             const TextureOptions& o, double scale) {
  TexturedMesh out;
  const double inv = 1.0 / o.atlas_size_px;
  for (std::size_t ci = 0; ci < charts.size(); ++ci) {
    const Chart& c = charts[ci];
    std::unordered_map<int, int> index;
    for (int f : c.faces) {
      std::array<int, 3> nf;
      for (int k = 0; k < 3; ++k) {
        const int v = m.faces[std::size_t(f)][std::size_t(k)];
        auto [it, fresh] = index.try_emplace(v, int(out.mesh.vertices.size()));
        if (fresh) {
          out.mesh.vertices.push_back(m.vertices[std::size_t(v)]);
          if (!m.normals.empty()) out.mesh.normals.push_back(m.normals[std::size_t(v)]);
          const Eigen::Vector2d q = c.view == kNoView
                                        ? Eigen::Vector2d(c.x + o.gutter_px + 0.5 * kGreyPatchPx - 0.5,
                                                          c.y + o.gutter_px + 0.5 * kGreyPatchPx - 0.5)
                                        : texel_of(c, pixels[ci].at(v), o.gutter_px, scale);
          // Texel centre i sits at (i + 0.5) / size in glTF's [0, 1] coordinates.
          out.uv.push_back(((q.array() + 0.5) * inv).cast<float>());
        }
        nf[std::size_t(k)] = it->second;
      }
      out.mesh.faces.push_back(nf);
      out.face_atlas.push_back(c.page);
      out.face_view.push_back(c.view);
    }
  }

  return out;
}

TextureSummary texture_summary(const DenseMesh& m, const std::vector<OrthoView>& views, const std::vector<int>& label,
                               const FaceCandidates& cand, const FaceGeometry& g, std::size_t charts, int pages,
                               double scale) {
  TextureSummary s;
  s.views = int(views.size());
  s.faces = m.faces.size();
  s.charts = charts;
  s.atlases = pages;
  s.texel_scale = scale;
  s.faces_per_view.assign(views.size(), 0);
  for (const auto& v : views) s.view_names.push_back(v.name);
  std::vector<double> texel_m;
  std::size_t interior = 0, seams = 0;
  for (std::size_t f = 0; f < label.size(); ++f) {
    if (label[f] == kNoView) continue;
    ++s.textured_faces;
    ++s.faces_per_view[std::size_t(label[f])];
    for (int j = 0; j < cand.k; ++j)
      if (cand.view[f * cand.k + j] == label[f]) texel_m.push_back(cand.texel_m[f * cand.k + j] / scale);
    for (int nb : g.neighbours[f]) {
      if (nb < 0) continue;
      ++interior;
      seams += label[std::size_t(nb)] != label[f] ? 1 : 0;
    }
  }
  for (std::size_t n : s.faces_per_view) s.views_used += n > 0 ? 1 : 0;
  if (!texel_m.empty()) s.median_texel_m = median_in_place(texel_m);
  s.seam_fraction = interior ? double(seams) / interior : 0;
  return s;
}

}  // namespace

TexturedMesh build_texture_atlas(const DenseMesh& m, const std::vector<OrthoView>& views, const TextureOptions& o,
                                 TextureSummary* summary) {
  o.validate();
  const Stopwatch clock;
  if (m.faces.empty()) throw InputError("products.texture: the mesh has no faces");
  const FaceGeometry g = face_geometry(m);

  FaceCandidates cand(m.faces.size(), o.candidates);
  for (std::size_t v = 0; v < views.size(); ++v) score_view(m, g, views[v], int(v), o, cand);
  const std::vector<int> label = smooth_labels(cand, g, o);
  // Without colour balance: no overlaps, every gain 1.
  const ColourGains gains = o.colour_balance ? face_colour_gains(cand, int(views.size()))
                                             : fit_colour_gains(ColourOverlaps{}, int(views.size()));

  std::vector<Chart> charts = grow_charts(label, g);
  ChartPixels pixels;
  for (Chart& c : charts) {
    pixels.push_back(project_chart(c, m, views[std::size_t(c.view)].camera));
    chart_bounds(c, pixels.back());
  }
  Chart grey;  // untextured faces
  for (std::size_t f = 0; f < label.size(); ++f)
    if (label[f] == kNoView) grey.faces.push_back(int(f));
  if (!grey.faces.empty()) {
    charts.push_back(grey);
    pixels.emplace_back();
  }
  double scale = 1;
  const int pages = fit_charts(charts, pixels, m, o, scale);
  std::vector<Page> atlas = paint_atlases(charts, pixels, grey, m, views, gains.gains, o, pages, scale);
  TexturedMesh out = textured_output(charts, pixels, m, o, scale);
  for (Page& p : atlas) out.atlases.push_back(std::move(p.image));
  out.view_gains = gains.gains;
  if (summary) {
    *summary = texture_summary(m, views, label, cand, g, charts.size() - (grey.faces.empty() ? 0 : 1), pages, scale);
    summary->gains = gains.gains;
    summary->balance_rms_before = gains.rms_before;
    summary->balance_rms_after = gains.rms_after;
    summary->balance_overlaps = gains.overlaps;
    summary->seconds = clock.seconds();
  }
  return out;
}

std::string encode_texture_image(const TextureImage& image, int jpeg_quality) {
  if (jpeg_quality < 0 || jpeg_quality > 100)
    throw InputError(fmt::format("products.texture: JPEG quality must be in [1, 100] (0: PNG), got {}", jpeg_quality));
  const cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<std::uint8_t*>(image.rgb.data()));
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  std::vector<std::uint8_t> bytes;
  const bool ok = jpeg_quality > 0 ? cv::imencode(".jpg", bgr, bytes, {cv::IMWRITE_JPEG_QUALITY, jpeg_quality})
                                   : cv::imencode(".png", bgr, bytes);
  if (!ok) throw ProcessingError("products.texture: the atlas could not be encoded");
  return std::string(bytes.begin(), bytes.end());
}

}  // namespace strata
