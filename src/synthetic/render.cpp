#include "synthetic/render.hpp"

#include "core/error.hpp"
#include "synthetic/noise.hpp"

#include <opencv2/imgproc.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>

namespace strata::synthetic {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kFar = 60.0;            // metres: rays travelling further see the sky
constexpr double kTrenchPad = 0.05;      // metres around the trench re-textured per layer
constexpr double kAoCell = 0.01;         // metres, ambient-occlusion grid
constexpr double kAoWideSigma = 0.12;    // metres: concavity at the scale of trench and pit
constexpr double kAoNarrowSigma = 0.02;  // metres: crevices between stones and pebbles
constexpr double kSteepStart = 0.45;     // normal z below which faces are textured as sections
constexpr double kSteepEnd = 0.6;        // normal z above which floors use the baked texture
constexpr double kEdgeDepthRatio = 0.02; // relative depth jump that marks an edge pixel
const Rgb kSkyRadiance{1.25f, 1.3f, 1.4f};

struct SrgbTables {
  std::array<float, 256> decode{};
  std::array<std::uint8_t, 4097> encode{};
  SrgbTables() {
    for (int i = 0; i < 256; ++i) {
      const double s = i / 255.0;
      decode[std::size_t(i)] = float(s <= 0.04045 ? s / 12.92 : std::pow((s + 0.055) / 1.055, 2.4));
    }
    for (int i = 0; i <= 4096; ++i) {
      const double l = i / 4096.0;
      const double s = l <= 0.0031308 ? 12.92 * l : 1.055 * std::pow(l, 1 / 2.4) - 0.055;
      encode[std::size_t(i)] = std::uint8_t(std::lround(std::clamp(s, 0.0, 1.0) * 255.0));
    }
  }
};
const SrgbTables kSrgb;  // built at start-up, read-only afterwards
const SrgbTables& srgb() { return kSrgb; }
// Encoding through a 12-bit table: finer than the 8-bit output in the darks that
// matter (the table step is 1/4096 of white in linear light).
inline std::uint8_t encode(float linear) {
  return srgb().encode[std::size_t(std::clamp(linear, 0.0f, 1.0f) * 4096.0f + 0.5f)];
}
inline float decode(std::uint8_t s) { return srgb().decode[s]; }

// Visits the cells of a uniform grid (cell units) crossed by the 2D segment
// p(t) = o + t d, t in [ta, tb]; visit(i, j, t_in, t_out) returns true to stop.
template <class Visit>
bool traverse(double ox, double oy, double dx, double dy, double ta, double tb, int nx, int ny,
              Visit&& visit) {
  const double px = ox + ta * dx, py = oy + ta * dy;
  int i = std::clamp(int(std::floor(px)), 0, nx - 1), j = std::clamp(int(std::floor(py)), 0, ny - 1);
  const int si = dx > 0 ? 1 : -1, sj = dy > 0 ? 1 : -1;
  const double idx = dx != 0 ? 1.0 / dx : kInf, idy = dy != 0 ? 1.0 / dy : kInf;
  double tmx = dx != 0 ? ta + (double(i + (dx > 0 ? 1 : 0)) - px) * idx : kInf;
  double tmy = dy != 0 ? ta + (double(j + (dy > 0 ? 1 : 0)) - py) * idy : kInf;
  const double tdx = std::abs(idx), tdy = std::abs(idy);
  double t = ta;
  while (true) {
    const double tn = std::max(t, std::min({tmx, tmy, tb}));
    if (visit(i, j, t, tn)) return true;
    if (tn >= tb) return false;
    if (tmx < tmy) {
      i += si;
      tmx += tdx;
      if (i < 0 || i >= nx) return false;
    } else {
      j += sj;
      tmy += tdy;
      if (j < 0 || j >= ny) return false;
    }
    t = tn;
  }
}

// Intersection with the analytic ground on [ta, tb], conservative steps
// (the step never passes the surface because |grad G| <= lipschitz).
std::optional<double> march_outer(const Scene& scene, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                  double ta, double tb, double lipschitz) {
  const double denom = -d.z() + lipschitz * std::hypot(d.x(), d.y());
  if (denom <= 1e-9) return std::nullopt;
  double t = ta;
  for (int it = 0; it < 400 && t <= tb; ++it) {
    const Eigen::Vector3d p = o + t * d;
    const double f = p.z() - scene.ground_smooth(p.x(), p.y());
    if (f < 1e-6) return t;
    t += f / denom;
  }
  return std::nullopt;
}

Eigen::Vector3d outer_normal(const Scene& scene, double x, double y) {
  constexpr double h = 0.01;
  const double gx = (scene.ground_smooth(x + h, y) - scene.ground_smooth(x - h, y)) / (2 * h);
  const double gy = (scene.ground_smooth(x, y + h) - scene.ground_smooth(x, y - h)) / (2 * h);
  return Eigen::Vector3d(-gx, -gy, 1).normalized();
}

}  // namespace

Rgb shade(const Lighting& light, const Eigen::Vector3d& n, double ao) {
  const double sun = std::max(0.0, n.dot(light.sun)) * std::sqrt(ao);  // soft shadow proxy
  const double sky = ao * (0.6 + 0.4 * std::max(n.z(), 0.0));
  return light.sky_colour * float(sky) + light.sun_colour * float(sun);
}

// ---- LayerTexture ---------------------------------------------------------------

LayerTexture::LayerTexture(const Scene& scene, int layer, const Lighting& light, double texel,
                           const LayerTexture* ground) {
  const HeightGrid& g = scene.surface(layer);
  // Ambient occlusion from concavity: how far the surface lies below its blurred self.
  {
    ao_x0_ = g.x0;
    ao_y0_ = g.y0;
    ao_cell_ = kAoCell;
    ao_nx_ = int((g.x1() - g.x0) / kAoCell) + 1;
    ao_ny_ = int((g.y1() - g.y0) / kAoCell) + 1;
    cv::Mat h(ao_ny_, ao_nx_, CV_32F), wide, narrow;
    for (int j = 0; j < ao_ny_; ++j)
      for (int i = 0; i < ao_nx_; ++i) h.at<float>(j, i) = float(g.sample(g.x0 + i * kAoCell, g.y0 + j * kAoCell));
    cv::GaussianBlur(h, wide, cv::Size(), kAoWideSigma / kAoCell, 0, cv::BORDER_REPLICATE);
    cv::GaussianBlur(h, narrow, cv::Size(), kAoNarrowSigma / kAoCell, 0, cv::BORDER_REPLICATE);
    ao_.resize(std::size_t(ao_nx_) * std::size_t(ao_ny_));
    for (int j = 0; j < ao_ny_; ++j)
      for (int i = 0; i < ao_nx_; ++i) {
        const double z = h.at<float>(j, i);
        // Gains: 0.25 m below the wide blur (a trench floor at its side) halves the sky.
        const double a = std::clamp(1.0 - 2.0 * std::max(0.0, wide.at<float>(j, i) - z), 0.3, 1.0);
        const double b = std::clamp(1.0 - 8.0 * std::max(0.0, narrow.at<float>(j, i) - z), 0.6, 1.0);
        ao_[std::size_t(j) * std::size_t(ao_nx_) + std::size_t(i)] = float(a * b);
      }
  }

  x0_ = g.x0;
  y0_ = g.y0;
  Level base;
  base.texel = texel;
  base.nx = int(std::ceil((g.x1() - g.x0) / texel));
  base.ny = int(std::ceil((g.y1() - g.y0) / texel));
  const std::size_t n = std::size_t(base.nx) * std::size_t(base.ny);
  base.rgb.resize(3 * n);
  albedo_.resize(3 * n);
  const double px0 = scene.trench_x0() - kTrenchPad, px1 = scene.trench_x1() + kTrenchPad;
  const double py0 = scene.trench_y0() - kTrenchPad, py1 = scene.trench_y1() + kTrenchPad;
  const bool reuse = ground != nullptr && ground->albedo_.size() == albedo_.size();
  tbb::parallel_for(0, base.ny, [&](int j) {
    for (int i = 0; i < base.nx; ++i) {
      const double x = x0_ + (i + 0.5) * texel, y = y0_ + (j + 0.5) * texel;
      const std::size_t k = 3 * (std::size_t(j) * std::size_t(base.nx) + std::size_t(i));
      Rgb a;
      if (reuse && (x < px0 || x > px1 || y < py0 || y > py1)) {
        a = {decode(ground->albedo_[k]), decode(ground->albedo_[k + 1]), decode(ground->albedo_[k + 2])};
        albedo_[k] = ground->albedo_[k];
        albedo_[k + 1] = ground->albedo_[k + 1];
        albedo_[k + 2] = ground->albedo_[k + 2];
      } else {
        const double z = g.sample(x, y);
        a = scene.albedo(scene.material_at(x, y, z, layer, true), x, y, texel);
        albedo_[k] = encode(a.r);
        albedo_[k + 1] = encode(a.g);
        albedo_[k + 2] = encode(a.b);
      }
      const Rgb r = a * shade(light, g.normal(x, y), ao(x, y));
      base.rgb[k] = encode(r.r);
      base.rgb[k + 1] = encode(r.g);
      base.rgb[k + 2] = encode(r.b);
    }
  });
  levels_.push_back(std::move(base));
  // Mip chain: 2 x 2 box filter in linear light.
  while (levels_.back().nx > 8 && levels_.back().ny > 8) {
    const Level& f = levels_.back();
    Level c;
    c.nx = (f.nx + 1) / 2;
    c.ny = (f.ny + 1) / 2;
    c.texel = 2 * f.texel;
    c.rgb.resize(3 * std::size_t(c.nx) * std::size_t(c.ny));
    for (int j = 0; j < c.ny; ++j)
      for (int i = 0; i < c.nx; ++i)
        for (int ch = 0; ch < 3; ++ch) {
          float sum = 0;
          int cnt = 0;
          for (int dj = 0; dj < 2; ++dj)
            for (int di = 0; di < 2; ++di) {
              const int fi = 2 * i + di, fj = 2 * j + dj;
              if (fi >= f.nx || fj >= f.ny) continue;
              sum += decode(f.rgb[3 * (std::size_t(fj) * std::size_t(f.nx) + std::size_t(fi)) + std::size_t(ch)]);
              ++cnt;
            }
          c.rgb[3 * (std::size_t(j) * std::size_t(c.nx) + std::size_t(i)) + std::size_t(ch)] = encode(sum / float(cnt));
        }
    levels_.push_back(std::move(c));
  }
}

Rgb LayerTexture::bilinear(const Level& l, double x, double y) const {
  const double gx = std::clamp((x - x0_) / l.texel - 0.5, 0.0, double(l.nx - 1));
  const double gy = std::clamp((y - y0_) / l.texel - 0.5, 0.0, double(l.ny - 1));
  const int i = std::min(int(gx), l.nx - 2), j = std::min(int(gy), l.ny - 2);
  const float u = float(gx - i), v = float(gy - j);
  const std::size_t a = 3 * (std::size_t(j) * std::size_t(l.nx) + std::size_t(i)), b = a + 3;
  const std::size_t c = a + 3 * std::size_t(l.nx), d = c + 3;
  float out[3];
  for (std::size_t ch = 0; ch < 3; ++ch) {
    const float top = decode(l.rgb[a + ch]) * (1 - u) + decode(l.rgb[b + ch]) * u;
    const float bottom = decode(l.rgb[c + ch]) * (1 - u) + decode(l.rgb[d + ch]) * u;
    out[ch] = top * (1 - v) + bottom * v;
  }
  return {out[0], out[1], out[2]};
}

Rgb LayerTexture::sample(double x, double y, double footprint) const {
  const double level = std::clamp(std::log2(std::max(footprint, 1e-9) / levels_[0].texel), 0.0,
                                  double(levels_.size() - 1));
  const int l0 = int(level);
  const double f = level - l0;
  const Rgb a = bilinear(levels_[std::size_t(l0)], x, y);
  if (f < 1e-3 || l0 + 1 >= int(levels_.size())) return a;
  return lerp(a, bilinear(levels_[std::size_t(l0 + 1)], x, y), f);
}

double LayerTexture::ao(double x, double y) const {
  const double gx = std::clamp((x - ao_x0_) / ao_cell_, 0.0, double(ao_nx_ - 1));
  const double gy = std::clamp((y - ao_y0_) / ao_cell_, 0.0, double(ao_ny_ - 1));
  const int i = std::min(int(gx), ao_nx_ - 2), j = std::min(int(gy), ao_ny_ - 2);
  const double u = gx - i, v = gy - j;
  auto at = [&](int a, int b) { return double(ao_[std::size_t(b) * std::size_t(ao_nx_) + std::size_t(a)]); };
  return (at(i, j) * (1 - u) + at(i + 1, j) * u) * (1 - v) + (at(i, j + 1) * (1 - u) + at(i + 1, j + 1) * u) * v;
}

// ---- ray casting ----------------------------------------------------------------

RayHit cast_ray(const Scene& scene, int layer, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  const double lipschitz = scene.ground_slope_bound() + 0.01;  // + margin for rounding
  RayHit hit;
  const HeightGrid& g = scene.surface(layer);
  auto found = [&](double t, RayHit::Where where) {
    hit.where = where;
    hit.t = t;
    hit.point = o + t * d;
    return hit;
  };

  // Slab test against the grid's xy rectangle.
  double t0 = 0, t1 = kFar;
  auto slab = [&](double oc, double dc, double lo, double hi) {
    if (std::abs(dc) < 1e-15) {
      if (oc < lo || oc > hi) t1 = -1;
      return;
    }
    double a = (lo - oc) / dc, b = (hi - oc) / dc;
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  };
  slab(o.x(), d.x(), g.x0, g.x1());
  slab(o.y(), d.y(), g.y0, g.y1());
  if (t0 >= t1) {
    if (auto t = march_outer(scene, o, d, 0, kFar, lipschitz)) return found(*t, RayHit::Where::outer);
    return hit;
  }
  if (t0 > 0)
    if (auto t = march_outer(scene, o, d, 0, t0, lipschitz)) return found(*t, RayHit::Where::outer);

  // Inside the grid: clip to the part of the ray below the highest node.
  const auto& pyramid = scene.max_pyramid(layer);
  const float gmax = scene.surface_max(layer);
  double ta = t0, tb = t1;
  if (d.z() < 0) ta = std::max(ta, (double(gmax) - o.z()) / d.z());
  else if (o.z() + ta * d.z() > gmax) ta = tb;  // going up above everything
  if (ta < tb) {
    const double c = g.cell;
    const double ox = (o.x() - g.x0) / c, oy = (o.y() - g.y0) / c, dx = d.x() / c, dy = d.y() / c;
    double t_hit = -1;
    // f(t) = ray height above the bilinear surface of cell (i, j).
    auto f_cell = [&](int i, int j, double t) {
      const double u = std::clamp(ox + t * dx - i, 0.0, 1.0), v = std::clamp(oy + t * dy - j, 0.0, 1.0);
      const double a = g.node(i, j), b = g.node(i + 1, j), cc = g.node(i, j + 1), dd = g.node(i + 1, j + 1);
      return o.z() + t * d.z() - (a + (b - a) * u + (cc - a) * v + (a - b - cc + dd) * u * v);
    };
    auto cell_hit = [&](int i, int j, double cin, double cout) {
      const double f0 = f_cell(i, j, cin);
      if (f0 <= 0) {
        t_hit = cin;
        return true;
      }
      const double f1 = f_cell(i, j, cout);
      if (f1 > 0) return false;
      // Along a line the bilinear patch is quadratic in t: fit through three
      // values and take the first root in the cell.
      const double fm = f_cell(i, j, 0.5 * (cin + cout));
      const double A = 2 * f1 + 2 * f0 - 4 * fm, B = f1 - f0 - A, C = f0;
      double s = f0 / (f0 - f1);  // secant, exact when the patch is planar along the ray
      if (std::abs(A) > 1e-12) {
        const double disc = std::max(0.0, B * B - 4 * A * C);
        const double q = -0.5 * (B + std::copysign(std::sqrt(disc), B));
        double best = 2.0;
        for (double r : {q / A, q != 0 ? C / q : 2.0})
          if (r >= -1e-9 && r <= 1 + 1e-9) best = std::min(best, r);
        if (best <= 1) s = best;
      }
      t_hit = cin + std::clamp(s, 0.0, 1.0) * (cout - cin);
      return true;
    };
    // Descend the max pyramid: a block the ray passes entirely above is skipped.
    auto visit = [&](auto&& self, int level, int i, int j, double tin, double tout) -> bool {
      if (level == 0) return cell_hit(i, j, tin, tout);
      const Scene::MaxLevel& L = pyramid[std::size_t(level)];
      const double zlo = std::min(o.z() + tin * d.z(), o.z() + tout * d.z());
      if (zlo > L.max[std::size_t(j) * std::size_t(L.nx) + std::size_t(i)] + 1e-6) return false;
      const Scene::MaxLevel& F = pyramid[std::size_t(level - 1)];
      const double b = F.block;
      return traverse(ox / b, oy / b, dx / b, dy / b, tin, tout, F.nx, F.ny,
                      [&](int ci, int cj, double a, double e) { return self(self, level - 1, ci, cj, a, e); });
    };
    const int top = int(pyramid.size()) - 1;
    const double b = pyramid[std::size_t(top)].block;
    traverse(ox / b, oy / b, dx / b, dy / b, ta, tb, pyramid[std::size_t(top)].nx, pyramid[std::size_t(top)].ny,
             [&](int i, int j, double a, double e) { return visit(visit, top, i, j, a, e); });
    if (t_hit >= 0) return found(t_hit, RayHit::Where::grid);
  }
  if (auto t = march_outer(scene, o, d, t1, kFar, lipschitz)) return found(*t, RayHit::Where::outer);
  return hit;
}

// ---- rendering --------------------------------------------------------------------

namespace {

struct Sample {
  Rgb colour;
  double t = kInf;  // metres; infinity for the sky
};

Sample shade_ray(const Scene& scene, int layer, const LayerTexture& tex, const Lighting& light,
                 const Camera& cam, const RenderSettings& settings, const Eigen::Vector3d& d,
                 double pixel_scale) {
  const Eigen::Vector3d o = cam.pose.centre();
  const RayHit hit = cast_ray(scene, layer, o, d);
  Sample s;
  if (hit.where == RayHit::Where::sky) {
    s.colour = kSkyRadiance;
    return s;
  }
  s.t = hit.t;
  const double x = hit.point.x(), y = hit.point.y(), z = hit.point.z();
  const double angular = pixel_scale / cam.intrinsics.fx;  // radians per (sub)pixel
  if (hit.where == RayHit::Where::outer) {
    const Eigen::Vector3d n = outer_normal(scene, x, y);
    const double fp = hit.t * angular / std::sqrt(std::max(std::abs(n.dot(d)), 0.05));
    s.colour = scene.albedo(Material{}, x, y, fp) * shade(light, n, 1.0);
    return s;
  }
  const HeightGrid& g = scene.surface(layer);
  const Eigen::Vector3d n = g.normal(x, y);
  const double cos_i = std::max(std::abs(n.dot(d)), 0.05);
  // Footprint in metres: isotropic compromise between the two axes of the
  // projected pixel (1 and 1/cos), so oblique floors are neither blurred nor aliased.
  const double fp = hit.t * angular / std::sqrt(cos_i);
  const double ao = tex.ao(x, y);
  Rgb colour;
  if (n.z() >= kSteepEnd) {
    colour = tex.sample(x, y, fp);
  } else {
    // A section or a stone face: texture on the vertical plane facing the normal.
    const bool faces_x = std::abs(n.x()) > std::abs(n.y());
    const Material m = scene.material_at(x, y, z, layer, false);
    const Rgb wall = scene.albedo(m, faces_x ? y : x, z, hit.t * angular / std::sqrt(cos_i)) * shade(light, n, ao);
    colour = n.z() <= kSteepStart ? wall
                                  : lerp(wall, tex.sample(x, y, fp), smoothstep(kSteepStart, kSteepEnd, n.z()));
  }
  // Printed targets and test spots lie on the surface and are lit like it.
  const Scene::Print print = scene.marker_print(x, y, fp);
  if (print.coverage > 0 || settings.spot) {
    const Rgb lit = shade(light, n, ao);
    if (print.coverage > 0) colour = lerp(colour, lit * float(print.reflectance), print.coverage);
    if (settings.spot) {
      const double r = (Eigen::Vector2d(x, y) - settings.spot->centre).norm();
      const double cov = smoothstep(settings.spot->radius + 0.5 * fp, settings.spot->radius - 0.5 * fp, r);
      if (cov > 0) colour = lerp(colour, settings.spot->reflectance * lit, cov);
    }
  }
  s.colour = colour;
  return s;
}

// Undistorted normalised coordinates of every pixel centre: the fixed-point
// inversion of the distortion is the costliest part of a ray, and every photo of
// a dataset shares one camera, so the last table is kept.
std::shared_ptr<const std::vector<Eigen::Vector2d>> undistorted_pixel_centres(const Intrinsics& k) {
  static std::mutex mutex;
  static Intrinsics cached_for;
  static std::shared_ptr<const std::vector<Eigen::Vector2d>> cached;
  std::lock_guard lock(mutex);
  const bool same = cached && cached_for.width == k.width && cached_for.height == k.height &&
                    cached_for.fx == k.fx && cached_for.fy == k.fy && cached_for.cx == k.cx &&
                    cached_for.cy == k.cy && cached_for.model == k.model && cached_for.k1 == k.k1 &&
                    cached_for.k2 == k.k2 && cached_for.k3 == k.k3 && cached_for.k4 == k.k4 &&
                    cached_for.p1 == k.p1 && cached_for.p2 == k.p2;
  if (!same) {
    auto table = std::make_shared<std::vector<Eigen::Vector2d>>(std::size_t(k.width) * std::size_t(k.height));
    tbb::parallel_for(0, k.height, [&](int v) {
      for (int u = 0; u < k.width; ++u)
        (*table)[std::size_t(v) * std::size_t(k.width) + std::size_t(u)] = k.to_normalised({double(u), double(v)});
    });
    cached = table;
    cached_for = k;
  }
  return cached;
}

}  // namespace

LinearImage render_view(const Scene& scene, int layer, const LayerTexture& texture, const Lighting& light,
                        const Camera& camera, const RenderSettings& settings) {
  const int w = camera.intrinsics.width, h = camera.intrinsics.height;
  STRATA_CHECK(w > 0 && h > 0, "camera without image size");
  LinearImage img;
  img.width = w;
  img.height = h;
  img.rgb.assign(3 * std::size_t(w) * std::size_t(h), 0.0f);
  std::vector<double> depth(std::size_t(w) * std::size_t(h), kInf);
  const auto normalised = undistorted_pixel_centres(camera.intrinsics);
  const Eigen::Matrix3d Rt = camera.pose.R.transpose();
  tbb::parallel_for(tbb::blocked_range<int>(0, h, 8), [&](const tbb::blocked_range<int>& rows) {
    for (int v = rows.begin(); v < rows.end(); ++v)
      for (int u = 0; u < w; ++u) {
        const std::size_t k = std::size_t(v) * std::size_t(w) + std::size_t(u);
        const Eigen::Vector2d& xn = (*normalised)[k];
        const Eigen::Vector3d d = (Rt * Eigen::Vector3d(xn.x(), xn.y(), 1.0)).normalized();
        const Sample s = shade_ray(scene, layer, texture, light, camera, settings, d, 1.0);
        depth[k] = s.t;
        img.rgb[3 * k] = s.colour.r;
        img.rgb[3 * k + 1] = s.colour.g;
        img.rgb[3 * k + 2] = s.colour.b;
      }
  });
  if (settings.edge_samples <= 0) return img;
  // Adaptive supersampling: extra rays where the depth jumps (occluding edges of
  // trench sides, stones, the pit rim and the horizon), on a rotated grid.
  static constexpr std::array<std::array<double, 2>, 8> kOffsets{
      {{0.125, -0.375}, {-0.375, -0.125}, {0.375, 0.125}, {-0.125, 0.375},
       {0.375, -0.375}, {-0.375, 0.375}, {0.25, 0.25}, {-0.25, -0.25}}};
  const int extra = std::min(settings.edge_samples, int(kOffsets.size()));
  std::vector<float> out = img.rgb;
  tbb::parallel_for(tbb::blocked_range<int>(0, h, 8), [&](const tbb::blocked_range<int>& rows) {
    for (int v = rows.begin(); v < rows.end(); ++v)
      for (int u = 0; u < w; ++u) {
        const std::size_t k = std::size_t(v) * std::size_t(w) + std::size_t(u);
        const double t = depth[k];
        bool edge = false;
        for (auto [du, dv] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
          const int uu = u + du, vv = v + dv;
          if (uu < 0 || vv < 0 || uu >= w || vv >= h) continue;
          const double tn = depth[std::size_t(vv) * std::size_t(w) + std::size_t(uu)];
          if (std::isinf(t) != std::isinf(tn) ||
              (!std::isinf(t) && std::abs(t - tn) > kEdgeDepthRatio * std::min(t, tn)))
            edge = true;
        }
        if (!edge) continue;
        Rgb sum{img.rgb[3 * k], img.rgb[3 * k + 1], img.rgb[3 * k + 2]};
        for (int e = 0; e < extra; ++e) {
          const Eigen::Vector2d p(u + kOffsets[std::size_t(e)][0], v + kOffsets[std::size_t(e)][1]);
          const Sample s = shade_ray(scene, layer, texture, light, camera, settings, camera.ray(p), 0.5);
          sum = sum + s.colour;
        }
        const float inv = 1.0f / float(1 + extra);
        out[3 * k] = sum.r * inv;
        out[3 * k + 1] = sum.g * inv;
        out[3 * k + 2] = sum.b * inv;
      }
  });
  img.rgb = std::move(out);
  return img;
}

}  // namespace strata::synthetic
