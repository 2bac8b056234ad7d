#include "synthetic/scene.hpp"

#include "core/error.hpp"
#include "synthetic/noise.hpp"

#include <opencv2/aruco.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace strata::synthetic {
namespace {

constexpr double kPi = 3.141592653589793;
constexpr double kGridMargin = 1.2;       // metres of fine grid around the trench
constexpr double kOuterFade = 0.15;       // metres over which micro-relief fades at the grid edge
constexpr double kWallRamp = 0.025;       // metres: horizontal width of the trench side
constexpr double kEdgeWiggle = 0.008;     // metres: irregularity of the trench edge
constexpr double kSurfaceSkin = 0.015;    // metres: weathered ground-surface skin
constexpr double kClassifyTol = 0.006;    // metres: tolerance of the interface test
constexpr double kStoneTol = 0.003;       // metres: a point this close to a stone top is stone
constexpr double kMarkerFlatPad = 0.03;   // metres beyond the target's half diagonal kept flat

// Colours and clasts of one kind of soil. Colours are given in sRGB (Munsell-like
// field colours) and converted to linear reflectance.
struct Clasts {
  double cell = 0, density = 0, rmin = 0, rmax = 0;  // metres, probability, metres
  Rgb dark, light;
};
struct Soil {
  Rgb base, alt;             // two tones mixed by large-scale mottling
  double mottle = 0.4;       // metres, longest mottling wavelength
  double variation = 0.18;   // relative brightness variation (cm..dm scale)
  double grain = 0.10;       // relative brightness variation (mm scale)
  double relief = 0.0035;    // metres, micro-relief amplitude
  Clasts pebbles, gravel, flecks;
  Rgb patch;                 // vegetation on the ground surface
  double patch_cover = 0;    // 0..1
};

Soil make_soil(int palette) {
  Soil s;
  switch (palette) {
    case 0:  // ground surface: dry trampled loam, grass tufts, scattered stones
      s.base = from_srgb8(150, 128, 98);
      s.alt = from_srgb8(172, 152, 116);
      s.pebbles = {0.06, 0.35, 0.006, 0.018, from_srgb8(120, 112, 100), from_srgb8(205, 196, 176)};
      s.gravel = {0.012, 0.3, 0.0012, 0.003, from_srgb8(95, 85, 70), from_srgb8(190, 180, 160)};
      s.flecks = {0.02, 0.25, 0.002, 0.006, from_srgb8(150, 140, 80), from_srgb8(190, 175, 110)};
      s.patch = from_srgb8(98, 112, 58);
      s.patch_cover = 0.8;
      s.relief = 0.004;
      break;
    case 1:  // topsoil in section / unit 101: dark greyish-brown loam
      s.base = from_srgb8(96, 77, 58);
      s.alt = from_srgb8(110, 88, 64);
      s.pebbles = {0.07, 0.25, 0.005, 0.016, from_srgb8(90, 84, 76), from_srgb8(180, 170, 150)};
      s.gravel = {0.012, 0.2, 0.001, 0.003, from_srgb8(60, 50, 40), from_srgb8(160, 150, 130)};
      s.flecks = {0.015, 0.15, 0.001, 0.002, from_srgb8(150, 120, 80), from_srgb8(180, 150, 100)};
      break;
    case 2:  // brown silty clay
      s.base = from_srgb8(132, 96, 66);
      s.alt = from_srgb8(116, 86, 60);
      s.pebbles = {0.05, 0.3, 0.005, 0.016, from_srgb8(100, 94, 86), from_srgb8(200, 190, 170)};
      s.gravel = {0.012, 0.25, 0.001, 0.0028, from_srgb8(70, 58, 46), from_srgb8(185, 170, 145)};
      s.flecks = {0.02, 0.12, 0.001, 0.002, from_srgb8(210, 200, 180), from_srgb8(230, 220, 200)};
      break;
    case 3:  // orange-brown clay with charcoal flecks
      s.base = from_srgb8(160, 106, 66);
      s.alt = from_srgb8(142, 96, 62);
      s.pebbles = {0.07, 0.2, 0.005, 0.014, from_srgb8(110, 100, 90), from_srgb8(200, 188, 168)};
      s.gravel = {0.012, 0.2, 0.001, 0.0025, from_srgb8(90, 60, 40), from_srgb8(190, 160, 120)};
      s.flecks = {0.014, 0.3, 0.0008, 0.0025, from_srgb8(32, 28, 26), from_srgb8(50, 44, 40)};
      break;
    case 4:  // pale yellowish sandy gravel (natural)
      s.base = from_srgb8(186, 170, 138);
      s.alt = from_srgb8(168, 150, 118);
      s.pebbles = {0.04, 0.45, 0.005, 0.015, from_srgb8(110, 106, 100), from_srgb8(225, 220, 205)};
      s.gravel = {0.01, 0.5, 0.0012, 0.0035, from_srgb8(95, 90, 85), from_srgb8(235, 230, 215)};
      s.flecks = {0.02, 0.1, 0.001, 0.002, from_srgb8(140, 100, 60), from_srgb8(160, 120, 70)};
      s.grain = 0.14;
      break;
    default:  // further units: greyish ashy silt
      s.base = from_srgb8(140, 134, 124);
      s.alt = from_srgb8(122, 116, 108);
      s.pebbles = {0.06, 0.25, 0.005, 0.015, from_srgb8(90, 86, 80), from_srgb8(200, 195, 185)};
      s.gravel = {0.012, 0.3, 0.001, 0.003, from_srgb8(50, 46, 44), from_srgb8(190, 185, 175)};
      s.flecks = {0.016, 0.25, 0.0008, 0.002, from_srgb8(30, 28, 28), from_srgb8(60, 56, 52)};
      break;
  }
  return s;
}

const char* deposit_description(int palette) {
  switch (palette) {
    case 1: return "topsoil: dark greyish-brown loam with roots and small stones";
    case 2: return "brown silty clay with pebbles; fills the pit cut";
    case 3: return "orange-brown clay with charcoal flecks";
    case 4: return "pale yellowish sandy gravel (natural, not excavated)";
    default: return "greyish ashy silt";
  }
}

int palette_of(int kind) { return kind <= 4 ? kind : 5; }

// Built once: the per-pixel texture code must not recompute colour conversions.
const Soil& soil_for(int kind) {
  static const std::array<Soil, 6> table = [] {
    std::array<Soil, 6> t;
    for (int i = 0; i < 6; ++i) t[std::size_t(i)] = make_soil(i);
    return t;
  }();
  return table[std::size_t(palette_of(kind))];
}

struct StoneColours {
  Rgb light = from_srgb8(176, 170, 158), grey = from_srgb8(158, 156, 150), dirt = from_srgb8(140, 108, 78);
};
const StoneColours& stone_colours() {
  static const StoneColours c;
  return c;
}

// A periodic wave (amplitude, kx, ky, phase) evaluated at (x, y).
double wave(const std::array<double, 4>& w, double x, double y) {
  return w[0] * std::sin(w[1] * x + w[2] * y + w[3]);
}

}  // namespace

Rgb from_srgb8(int r, int g, int b) {
  auto lin = [](int c) {
    const double s = c / 255.0;
    return float(s <= 0.04045 ? s / 12.92 : std::pow((s + 0.055) / 1.055, 2.4));
  };
  return {lin(r), lin(g), lin(b)};
}

// ---- HeightGrid --------------------------------------------------------------

double HeightGrid::sample(double x, double y) const {
  const double gx = std::clamp((x - x0) / cell, 0.0, double(nx - 1));
  const double gy = std::clamp((y - y0) / cell, 0.0, double(ny - 1));
  const int i = std::min(int(gx), nx - 2), j = std::min(int(gy), ny - 2);
  const double u = gx - i, v = gy - j;
  const double a = node(i, j), b = node(i + 1, j), c = node(i, j + 1), d = node(i + 1, j + 1);
  return a + (b - a) * u + (c - a) * v + (a - b - c + d) * u * v;
}

Eigen::Vector2d HeightGrid::gradient(double x, double y) const {
  return {(sample(x + cell, y) - sample(x - cell, y)) / (2 * cell),
          (sample(x, y + cell) - sample(x, y - cell)) / (2 * cell)};
}

Eigen::Vector3d HeightGrid::normal(double x, double y) const {
  const Eigen::Vector2d g = gradient(x, y);
  return Eigen::Vector3d(-g.x(), -g.y(), 1.0).normalized();
}

// ---- Scene -------------------------------------------------------------------

Scene::Scene(const SyntheticExcavationOptions& options) : options_(options) {
  options_.validate();
  stages_ = options_.site.stages;
  layout(options_.seed);
  build_surfaces();
  build_records();
}

void Scene::layout(std::uint64_t seed) {
  Rng rng(seed);
  seed32_ = std::uint32_t(mix64(seed ^ 0x5EEDull) >> 32);
  const auto& site = options_.site;
  // Trench corner a few tens of metres from the origin, off any round number.
  tx0_ = 11.0 + rng.uniform(0.0, 1.0);
  ty0_ = 17.0 + rng.uniform(0.0, 1.0);
  tx1_ = tx0_ + site.trench_size_e;
  ty1_ = ty0_ + site.trench_size_n;

  // Ground: 1450.3-1450.7 m at the trench, a 1.5-4 % slope, gentle undulations.
  g0_ = rng.uniform(0.3, 0.7);
  const double slope = rng.uniform(0.015, 0.04), slope_dir = rng.uniform(0, 2 * kPi);
  gsx_ = slope * std::cos(slope_dir);
  gsy_ = slope * std::sin(slope_dir);
  auto random_wave = [&](double amp_lo, double amp_hi, double len_lo, double len_hi) {
    const double amp = rng.uniform(amp_lo, amp_hi), len = rng.uniform(len_lo, len_hi);
    const double dir = rng.uniform(0, 2 * kPi), k = 2 * kPi / len;
    return std::array<double, 4>{amp, k * std::cos(dir), k * std::sin(dir), rng.uniform(0, 2 * kPi)};
  };
  for (int i = 0; i < 3; ++i) ground_waves_.push_back(random_wave(0.01, 0.03, 3.0, 8.0));
  ground_slope_bound_ = std::hypot(gsx_, gsy_);
  for (const auto& w : ground_waves_) ground_slope_bound_ += w[0] * std::hypot(w[1], w[2]);
  // Unit thickness fields: a mean level and three waves of 1.5-5 m wavelength.
  unit_mean_.assign(std::size_t(stages_ + 1), 0.5);
  unit_waves_.resize(std::size_t(stages_ + 1));
  for (int j = 1; j <= stages_; ++j) {
    unit_mean_[std::size_t(j)] = rng.uniform(0.35, 0.65);
    for (int i = 0; i < 3; ++i) unit_waves_[std::size_t(j)].push_back(random_wave(0.5, 1.0, 1.5, 5.0));
  }
  edge_seed_ = std::uint32_t(rng.next());

  // Pit: cut from the top of unit p+1 and filled by unit p, in the western part.
  const double se = site.trench_size_e, sn = site.trench_size_n;
  pit_.cut_from = std::min(2, stages_);
  pit_.c = {tx0_ + se * rng.uniform(0.22, 0.33), ty0_ + sn * rng.uniform(0.38, 0.62)};
  pit_.a = std::min(rng.uniform(0.32, 0.42), 0.12 * se);
  pit_.b = std::min(rng.uniform(0.24, 0.32), 0.12 * sn);
  pit_.yaw = rng.uniform(0, kPi);
  pit_.depth = rng.uniform(0.22, 0.32);
  pit_.cos_yaw = std::cos(pit_.yaw);
  pit_.sin_yaw = std::sin(pit_.yaw);

  // Stone wall: two faces of blocks running north-south in the eastern part,
  // founded on the last (undug) unit, standing proud of it.
  const double wall_x = tx0_ + se * rng.uniform(0.68, 0.76);
  const double wall_y0 = ty0_ + std::min(0.35, 0.15 * sn);
  const double wall_y1 = ty0_ + sn * rng.uniform(0.62, 0.75);
  const int cap_level = std::max(stages_ - 2, 0);
  for (double face : {-0.14, 0.14}) {
    double y = wall_y0 + rng.uniform(0.0, 0.08);
    while (true) {
      Stone s;
      const double half_len = rng.uniform(0.10, 0.19);
      if (y + 2 * half_len > wall_y1) break;
      s.a = half_len;
      s.b = rng.uniform(0.075, 0.13);
      s.c = {wall_x + face + rng.uniform(-0.02, 0.02), y + half_len};
      s.yaw = kPi / 2 + rng.uniform(-0.25, 0.25);
      s.cos_yaw = std::cos(s.yaw);
      s.sin_yaw = std::sin(s.yaw);
      const double floor_z = interface_smooth(stages_, s.c.x(), s.c.y());
      s.base = floor_z - 0.05;
      s.top = std::min(floor_z + rng.uniform(0.17, 0.27),
                       interface_smooth(cap_level, s.c.x(), s.c.y()) - 0.035);
      s.tint = rng.uniform(0.82, 1.1);
      s.tilt = rng.uniform(-1.0, 1.0);
      stones_.push_back(s);
      y += 2 * half_len + rng.uniform(0.015, 0.04);
    }
  }

  // Markers: evenly around a rectangle 0.4 m outside the trench edge, jittered.
  const int n = site.markers;
  const double off = 0.4, w = se + 2 * off, h = sn + 2 * off, perimeter = 2 * (w + h);
  const double phase = rng.uniform(0.0, 1.0);
  auto dict = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50);
  for (int i = 0; i < n; ++i) {
    double s = std::fmod((i + phase + rng.uniform(-0.12, 0.12)) / n, 1.0) * perimeter;
    const double out = rng.uniform(-0.08, 0.1);
    Eigen::Vector2d p;
    if (s < w) {
      p = {tx0_ - off + s, ty0_ - off - out};
    } else if ((s -= w) < h) {
      p = {tx1_ + off + out, ty0_ - off + s};
    } else if ((s -= h) < w) {
      p = {tx1_ + off - s, ty1_ + off + out};
    } else {
      s -= w;
      p = {tx0_ - off - out, ty1_ + off - s};
    }
    MarkerTarget m;
    m.id = i + 1;
    m.name = "GCP" + std::to_string(m.id);
    m.centre = {p.x(), p.y(), 0.0};  // z from the built surface
    m.yaw = rng.uniform(0, 2 * kPi);
    m.size = site.marker_size;
    if (site.marker_pattern == SyntheticExcavationOptions::Site::MarkerPattern::quadrant) {
      // Chequered quadrant target: 3 x 3 black cells top-left and bottom-right inside
      // the 1-cell white border, so the black-white saddle sits at the print's centre.
      for (int r = 0; r < 8; ++r)
        for (int c = 0; c < 8; ++c) {
          const bool border = r == 0 || c == 0 || r == 7 || c == 7;
          m.white[std::size_t(r * 8 + c)] = border || ((r < 4) != (c < 4));
        }
    } else {
      cv::Mat bits;
      cv::aruco::drawMarker(dict, m.id, 6, bits, 1);  // 4x4 code + 1-cell black border
      for (int r = 0; r < 8; ++r)
        for (int c = 0; c < 8; ++c)
          m.white[std::size_t(r * 8 + c)] =
              (r == 0 || c == 0 || r == 7 || c == 7) ? 1 : (bits.at<std::uint8_t>(r - 1, c - 1) > 127);
    }
    markers_.push_back(m);
  }
  // Check points spread around the ring (for 8 markers and 2 checks: the 2nd and 6th).
  for (int c = 0; c < site.check_markers; ++c)
    markers_[std::size_t((1 + c * n / site.check_markers) % n)].check = true;
}

double Scene::ground_smooth(double x, double y) const {
  const double cx = 0.5 * (tx0_ + tx1_), cy = 0.5 * (ty0_ + ty1_);
  double z = g0_ + gsx_ * (x - cx) + gsy_ * (y - cy);
  for (const auto& w : ground_waves_) z += wave(w, x, y);
  return z;
}

double Scene::thickness(int unit, double x, double y) const {
  double s = 0, norm = 0;
  for (const auto& w : unit_waves_[std::size_t(unit)]) {
    s += wave(w, x, y);
    norm += w[0];
  }
  const double level = std::clamp(unit_mean_[std::size_t(unit)] + 0.55 * s / norm, 0.0, 1.0);
  const auto& site = options_.site;
  return site.min_unit_thickness + (site.max_unit_thickness - site.min_unit_thickness) * level;
}

double Scene::interface_smooth(int j, double x, double y) const {
  double z = ground_smooth(x, y);
  for (int u = 1; u <= j; ++u) z -= thickness(u, x, y);
  return z;
}

double Scene::pit_profile(double x, double y) const {
  const double dx = x - pit_.c.x(), dy = y - pit_.c.y();
  const double ca = pit_.cos_yaw, sa = pit_.sin_yaw;
  const double a = (ca * dx + sa * dy) / pit_.a, b = (-sa * dx + ca * dy) / pit_.b;
  const double r2 = a * a + b * b;
  if (r2 >= 1.0) return 0.0;
  // Flat-ish bottom, steep sides over the outer third of the radius.
  return pit_.depth * (1.0 - 0.12 * r2) * (1.0 - smoothstep(0.62, 1.0, std::sqrt(r2)));
}

double Scene::stone_height(double x, double y, int* which) const {
  double best = kNoHeight;
  for (std::size_t k = 0; k < stones_.size(); ++k) {
    const Stone& s = stones_[k];
    const double dx = x - s.c.x(), dy = y - s.c.y();
    if (std::abs(dx) > s.a + s.b || std::abs(dy) > s.a + s.b) continue;
    const double ca = s.cos_yaw, sa = s.sin_yaw;
    const double a = (ca * dx + sa * dy) / s.a, b = (-sa * dx + ca * dy) / s.b;
    // Squarish footprint (superellipse of degree 4): roughly dressed blocks.
    const double r4 = a * a * a * a + b * b * b * b;
    if (r4 >= 1.0) continue;
    // Flat, slightly tilted top; steep faces rounded at the arris; a few mm of
    // roughness at 1-3 cm.
    const double h = s.base + (s.top - s.base) * std::pow(1.0 - r4, 0.22) + 0.03 * s.tilt * a +
                     0.005 * fbm(x, y, 0.04, 3, 0.002, seed32_ + 77u + std::uint32_t(k));
    if (h > best) {
      best = h;
      if (which) *which = int(k);
    }
  }
  return best;
}

double Scene::trench_weight(double x, double y) const {
  auto wig = [&](double t, std::uint32_t s) { return kEdgeWiggle * value_noise(t / 0.15, 0.5, edge_seed_ + s); };
  const double d = std::min({x - tx0_ + wig(y, 1), tx1_ - x + wig(y, 2), y - ty0_ + wig(x, 3),
                             ty1_ - y + wig(x, 4)});
  return smoothstep(0.0, kWallRamp, d);
}

double Scene::micro_relief(int surface, double x, double y) const {
  const int kind = surface == 0 ? 0 : surface + 1;  // the material exposed on that surface
  const Soil& soil = soil_for(kind);
  const std::uint32_t s = seed32_ + 7919u * std::uint32_t(kind);
  const double cell = options_.render.height_cell;
  double z = soil.relief * fbm(x, y, 0.2, 6, cell, s + 11u);
  const Clast p = clast_at(x, y, soil.pebbles.cell, soil.pebbles.density, soil.pebbles.rmin,
                           soil.pebbles.rmax, cell, s + 21u);
  return z + p.coverage * p.height;
}

void Scene::build_surfaces() {
  const double cell = options_.render.height_cell;
  HeightGrid proto;
  proto.cell = cell;
  proto.x0 = tx0_ - kGridMargin;
  proto.y0 = ty0_ - kGridMargin;
  proto.nx = int(std::ceil((tx1_ - tx0_ + 2 * kGridMargin) / cell)) + 1;
  proto.ny = int(std::ceil((ty1_ - ty0_ + 2 * kGridMargin) / cell)) + 1;
  proto.z.assign(std::size_t(proto.nx) * std::size_t(proto.ny), 0.0f);
  surfaces_.assign(std::size_t(layers()), proto);
  const int p = pit_.cut_from;
  const double gx1 = proto.x1(), gy1 = proto.y1();

  tbb::parallel_for(0, proto.ny, [&](int j) {
    std::vector<double> s(static_cast<std::size_t>(layers()));
    for (int i = 0; i < proto.nx; ++i) {
      const double x = proto.x0 + i * cell, y = proto.y0 + j * cell;
      // Ground: micro-relief fades out at the grid edge (to meet the analytic
      // ground beyond) and under each printed target (which lies flat).
      const double edge = std::min({x - proto.x0, gx1 - x, y - proto.y0, gy1 - y});
      double keep = smoothstep(0.0, kOuterFade, edge);
      for (const auto& m : markers_) {
        const double r = (Eigen::Vector2d(x, y) - m.centre.head<2>()).norm();
        const double flat = 0.5 * std::sqrt(2.0) * m.size;
        keep *= smoothstep(flat, flat + kMarkerFlatPad, r);
      }
      const double ground = ground_smooth(x, y);
      s[0] = ground + keep * micro_relief(0, x, y);
      const double w = trench_weight(x, y);
      if (w <= 0.0) {
        for (int k = 1; k < layers(); ++k) s[std::size_t(k)] = s[0];
      } else {
        const double stone = stone_height(x, y);
        double b = ground, top_p = 0;
        for (int k = 1; k < layers(); ++k) {
          b -= thickness(k, x, y);
          double inner = b + micro_relief(k, x, y);
          if (k == p) top_p = inner;
          if (k >= p) inner = std::min(inner, top_p - pit_profile(x, y));
          inner = std::max(inner, stone);
          // Later surfaces never rise above earlier ones.
          s[std::size_t(k)] = std::min((1 - w) * s[0] + w * inner, s[std::size_t(k - 1)]);
        }
      }
      for (int k = 0; k < layers(); ++k)
        surfaces_[std::size_t(k)].z[std::size_t(j) * std::size_t(proto.nx) + std::size_t(i)] =
            float(s[std::size_t(k)]);
    }
  });

  for (auto& m : markers_) m.centre.z() = surfaces_[0].sample(m.centre.x(), m.centre.y());

  // Max-height pyramid for empty-space skipping: factor 4 per level.
  pyramids_.assign(std::size_t(layers()), {});
  for (int k = 0; k < layers(); ++k) {
    const HeightGrid& g = surfaces_[std::size_t(k)];
    auto& pyr = pyramids_[std::size_t(k)];
    pyr.push_back(MaxLevel{1, g.nx - 1, g.ny - 1, {}});  // level 0: the cells themselves
    // Three levels (4, 16, 64 cells): coarser blocks only add descent overhead.
    while (pyr.size() < 4 && (pyr.back().nx > 1 || pyr.back().ny > 1)) {
      const MaxLevel& f = pyr.back();
      MaxLevel c;
      c.block = 4 * f.block;
      c.nx = (f.nx + 3) / 4;
      c.ny = (f.ny + 3) / 4;
      c.max.assign(std::size_t(c.nx) * std::size_t(c.ny), -1e30f);
      for (int j = 0; j < c.ny; ++j)
        for (int i = 0; i < c.nx; ++i) {
          float mx = -1e30f;
          if (pyr.size() == 1) {  // from nodes: a cell's maximum is one of its corners
            for (int n = 4 * j; n <= std::min(4 * j + 4, g.ny - 1); ++n)
              for (int m = 4 * i; m <= std::min(4 * i + 4, g.nx - 1); ++m) mx = std::max(mx, g.node(m, n));
          } else {
            for (int n = 4 * j; n < std::min(4 * j + 4, f.ny); ++n)
              for (int m = 4 * i; m < std::min(4 * i + 4, f.nx); ++m)
                mx = std::max(mx, f.max[std::size_t(n) * std::size_t(f.nx) + std::size_t(m)]);
          }
          c.max[std::size_t(j) * std::size_t(c.nx) + std::size_t(i)] = mx;
        }
      pyr.push_back(std::move(c));
    }
    const auto& top = pyr.back().max;
    surface_max_.push_back(*std::max_element(top.begin(), top.end()));
  }
}

void Scene::build_records() {
  const int K = stages_;
  auto code = [](int index) { return std::to_string(100 + index); };
  for (int j = 1; j <= K + 1; ++j) units_.push_back({code(j), "deposit", deposit_description(palette_of(j))});
  const std::string cut = code(K + 2), wall = code(K + 3);
  const int p = pit_.cut_from;
  units_.push_back({cut, "cut", "cut of an oval pit with steep sides, filled by " + code(p)});
  units_.push_back({wall, "structure", "stone wall foundation: two faces of limestone blocks"});

  for (int j = 1; j <= K; ++j) relations_.push_back({code(j), "above", code(j + 1)});
  relations_.push_back({code(p), "fills", cut});
  relations_.push_back({cut, "cuts", code(p + 1)});
  // Does the pit reach below the top of unit p+2 anywhere? Check on the grid.
  if (p + 2 <= K + 1) {
    const HeightGrid& g = surfaces_[std::size_t(K)];
    bool deeper = false;
    for (int j = 0; j < g.ny && !deeper; ++j)
      for (int i = 0; i < g.nx && !deeper; ++i) {
        const double x = g.x0 + i * g.cell, y = g.y0 + j * g.cell;
        if (pit_profile(x, y) > 0 && g.node(i, j) < interface_smooth(p + 1, x, y) - kClassifyTol)
          deeper = true;
      }
    if (deeper) relations_.push_back({cut, "cuts", code(p + 2)});
  }
  const int cover = std::max(K - 1, 1);
  relations_.push_back({code(cover), "above", wall});
  if (K != cover) relations_.push_back({code(K), "abuts", wall});
  relations_.push_back({wall, "above", code(K + 1)});
}

std::string Scene::layer_unit_code(int layer) const { return std::to_string(101 + layer); }

Material Scene::material_at(double x, double y, double z, int layer, bool floor) const {
  Material m;
  if (layer == 0 || trench_weight(x, y) <= 0.0) return m;  // the untouched ground
  int which = -1;
  if (stone_height(x, y, &which) >= z - kStoneTol) {
    m.kind = stone_kind();
    m.stone = which;
    return m;
  }
  if (z > ground_smooth(x, y) - kSurfaceSkin) return m;  // top edge of the trench side
  // A floor away from the pit shows the unit just exposed: no need to find it.
  if (floor && pit_profile(x, y) <= 0.0) {
    m.kind = layer + 1;
    return m;
  }
  int unit = 1;
  double b = ground_smooth(x, y);
  for (int j = 1; j <= stages_; ++j) {
    b -= thickness(j, x, y);
    if (z < b - kClassifyTol) unit = j + 1;
  }
  // A floor shows the unit just exposed (or one below it, in the pit); a section
  // shows whatever deposit lies at that height.
  m.kind = floor ? std::max(unit, layer + 1) : unit;
  return m;
}

Rgb Scene::albedo(const Material& m, double u, double v, double fp) const {
  const std::uint32_t s = seed32_ + 7919u * std::uint32_t(m.kind);
  if (m.kind == stone_kind()) {
    const Stone& st = stones_[std::size_t(std::max(m.stone, 0))];
    const std::uint32_t ss = s + 31u * std::uint32_t(m.stone + 1);
    const StoneColours& sc = stone_colours();
    Rgb c = lerp(sc.light, sc.grey, 0.5 + 0.5 * fbm(u, v, 0.12, 3, fp, ss));
    const double b = 1.0 + 0.16 * fbm(u, v, 0.05, 6, fp, ss + 1) + 0.08 * fbm(u, v, 0.003, 2, fp, ss + 2);
    c = c * float(st.tint * b);
    const Clast pit = clast_at(u, v, 0.008, 0.4, 0.0006, 0.0018, fp, ss + 3);  // weathering pits
    c = lerp(c, c * 0.55f, pit.coverage);
    // Patches of soil still clinging to the stone.
    const double dirt = smoothstep(0.25, 0.6, 0.5 + 0.5 * fbm(u, v, 0.1, 4, fp, ss + 4));
    return lerp(c, sc.dirt, 0.6 * dirt);
  }
  const Soil& soil = soil_for(m.kind);
  Rgb c = lerp(soil.base, soil.alt, smoothstep(0.25, 0.75, 0.5 + 0.5 * fbm(u, v, soil.mottle, 3, fp, s + 1)));
  const double b = 1.0 + soil.variation * fbm(u, v, 0.12, 6, fp, s + 2) + soil.grain * fbm(u, v, 0.004, 2, fp, s + 3);
  c = c * float(std::max(b, 0.2));
  if (soil.patch_cover > 0) {
    const double cover = smoothstep(0.5, 0.75, 0.5 + 0.5 * fbm(u, v, 0.8, 4, fp, s + 4)) * soil.patch_cover;
    if (cover > 0) {
      // Grass blades: streaks elongated along a fixed direction, light and dark.
      const double blades = 0.5 + 0.5 * fbm(u * 0.8 + v * 0.6, (v * 0.8 - u * 0.6) * 0.25, 0.02, 3, fp, s + 5);
      c = lerp(c, soil.patch * float(0.55 + 0.9 * blades), cover);
    }
  }
  auto overlay = [&](const Clasts& k, std::uint32_t seed) {
    const Clast cl = clast_at(u, v, k.cell, k.density, k.rmin, k.rmax, fp, seed);
    if (cl.coverage > 0) c = lerp(c, lerp(k.dark, k.light, cl.tone), cl.coverage);
  };
  overlay(soil.flecks, s + 41u);
  overlay(soil.gravel, s + 31u);
  overlay(soil.pebbles, s + 21u);  // same seed as the micro-relief bumps
  return c;
}

Scene::Print Scene::marker_print(double x, double y, double fp) const {
  constexpr double kPaperWhite = 0.82, kInkBlack = 0.035;  // matte print reflectance
  Print print;
  for (const auto& m : markers_) {
    const double dx = x - m.centre.x(), dy = y - m.centre.y(), half = 0.5 * m.size;
    if (std::abs(dx) > 0.75 * m.size + fp || std::abs(dy) > 0.75 * m.size + fp) continue;
    const double ca = std::cos(m.yaw), sa = std::sin(m.yaw);
    const double cell = m.size / 8.0;
    double refl = 0;
    // 2 x 2 samples over the footprint: antialiased edges of the printed cells.
    for (int s = 0; s < 4; ++s) {
      const double ox = (s & 1 ? 0.25 : -0.25) * fp, oy = (s & 2 ? 0.25 : -0.25) * fp;
      const double a = ca * (dx + ox) + sa * (dy + oy), b = -sa * (dx + ox) + ca * (dy + oy);
      if (std::abs(a) >= half || std::abs(b) >= half) continue;
      const int col = std::clamp(int((a + half) / cell), 0, 7), row = std::clamp(int((half - b) / cell), 0, 7);
      print.coverage += 0.25;
      refl += 0.25 * (m.white[std::size_t(row * 8 + col)] ? kPaperWhite : kInkBlack);
    }
    if (print.coverage > 0) {
      print.reflectance = refl / print.coverage;
      return print;
    }
  }
  return print;
}

}  // namespace strata::synthetic
