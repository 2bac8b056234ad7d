#include "report/coverage.hpp"

#include "core/statistics.hpp"
#include "core/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace strata {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// Bounding box of the recorded cells, in columns and rows.
struct CellBox {
  int c0 = 0, c1 = -1, r0 = 0, r1 = -1;
};
CellBox recorded_box(const CoverageMap& m) {
  CellBox b{m.width, -1, m.height, -1};
  for (int r = 0; r < m.height; ++r) {
    for (int c = 0; c < m.width; ++c) {
      if (!m.inside(m.index(c, r))) continue;
      b.c0 = std::min(b.c0, c);
      b.c1 = std::max(b.c1, c);
      b.r0 = std::min(b.r0, r);
      b.r1 = std::max(b.r1, r);
    }
  }
  return b;
}

// Sectors of the cells for which `is_short` holds, among those for which
// `counts` holds (the cells the fraction is taken over).
template <typename Short, typename Counts>
std::vector<CoverageShortfall> shortfalls(const CoverageMap& m, double min_fraction, Short is_short, Counts counts) {
  const CellBox b = recorded_box(m);
  std::vector<CoverageShortfall> out;
  if (b.c1 < b.c0) return out;
  const int w = b.c1 - b.c0 + 1, h = b.r1 - b.r0 + 1;
  struct Acc {
    int total = 0, cells = 0, min_count = std::numeric_limits<int>::max();
    double worst_gsd = 0;
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  };
  Acc acc[3][3];
  for (int r = b.r0; r <= b.r1; ++r) {
    for (int c = b.c0; c <= b.c1; ++c) {
      const std::size_t i = m.index(c, r);
      if (!m.inside(i) || !counts(i)) continue;
      const int sx = std::min(2, 3 * (c - b.c0) / w);
      const int sy = std::min(2, 3 * (b.r1 - r) / h);  // rows run north to south
      Acc& a = acc[sx][sy];
      ++a.total;
      if (!is_short(i)) continue;
      ++a.cells;
      a.min_count = std::min(a.min_count, m.count[i]);
      if (std::isfinite(m.gsd_m[i])) a.worst_gsd = std::max(a.worst_gsd, double(m.gsd_m[i]));
      a.sum += Eigen::Vector2d(m.x_centre(c), m.y_centre(r));
    }
  }
  for (int sy = 2; sy >= 0; --sy) {
    for (int sx = 0; sx < 3; ++sx) {
      const Acc& a = acc[sx][sy];
      if (a.total == 0 || a.cells == 0) continue;
      const double fraction = double(a.cells) / double(a.total);
      if (fraction < min_fraction) continue;
      CoverageShortfall s;
      s.sector = sector_of(sx, sy);
      s.centroid = a.sum / double(a.cells);
      s.cells = a.cells;
      s.fraction = fraction;
      s.area_m2 = a.cells * m.cell * m.cell;
      s.min_count = a.min_count;
      s.worst_gsd_m = a.worst_gsd;
      out.push_back(s);
    }
  }
  return out;
}

}  // namespace

bool CoverageMap::inside(std::size_t i) const { return std::isfinite(z[i]); }

std::size_t CoverageMap::area_cells() const {
  return std::size_t(std::count_if(z.begin(), z.end(), [](float v) { return std::isfinite(v); }));
}

CoverageMap coverage_grid(double x_min, double y_max, double cell, int width, int height, std::vector<float> z) {
  STRATA_CHECK(cell > 0 && width > 0 && height > 0, "empty coverage grid");
  STRATA_CHECK(z.size() == std::size_t(width) * std::size_t(height), "height grid size mismatch");
  CoverageMap m;
  m.x_min = x_min;
  m.y_max = y_max;
  m.cell = cell;
  m.width = width;
  m.height = height;
  m.z = std::move(z);
  m.count.assign(m.z.size(), 0);
  m.gsd_m.assign(m.z.size(), kNaN);
  return m;
}

CoverageMap coverage_grid_from_points(const std::vector<Eigen::Vector3d>& points, int max_cells) {
  STRATA_CHECK(max_cells >= 2, "max_cells must be at least 2");
  if (points.size() < 3) return {};
  std::vector<double> xs, ys;
  xs.reserve(points.size());
  ys.reserve(points.size());
  for (const auto& p : points) {
    xs.push_back(p.x());
    ys.push_back(p.y());
  }
  const double x0 = percentile(xs, 0.02), x1 = percentile(xs, 0.98);
  const double y0 = percentile(ys, 0.02), y1 = percentile(ys, 0.98);
  const double extent = std::max(x1 - x0, y1 - y0);
  if (!(extent > 0)) return {};
  const double cell = extent / max_cells;
  const int w = std::max(1, int(std::ceil((x1 - x0) / cell))), h = std::max(1, int(std::ceil((y1 - y0) / cell)));
  std::vector<std::vector<double>> zs(std::size_t(w) * std::size_t(h));
  for (const auto& p : points) {
    const int c = int(std::floor((p.x() - x0) / cell)), r = int(std::floor((y1 - p.y()) / cell));
    if (c < 0 || r < 0 || c >= w || r >= h) continue;
    zs[std::size_t(r) * std::size_t(w) + std::size_t(c)].push_back(p.z());
  }
  std::vector<float> z(zs.size(), kNaN);
  for (std::size_t i = 0; i < zs.size(); ++i) {
    if (!zs[i].empty()) z[i] = float(percentile(zs[i], 0.5));
  }
  // Fill empty cells from filled neighbours, ring by ring (a discrete nearest fill).
  for (bool changed = true; changed;) {
    changed = false;
    std::vector<float> next = z;
    for (int r = 0; r < h; ++r) {
      for (int c = 0; c < w; ++c) {
        const std::size_t i = std::size_t(r) * std::size_t(w) + std::size_t(c);
        if (std::isfinite(z[i])) continue;
        std::vector<double> near;
        for (int dr = -1; dr <= 1; ++dr) {
          for (int dc = -1; dc <= 1; ++dc) {
            const int cc = c + dc, rr = r + dr;
            if (cc < 0 || rr < 0 || cc >= w || rr >= h) continue;
            const float v = z[std::size_t(rr) * std::size_t(w) + std::size_t(cc)];
            if (std::isfinite(v)) near.push_back(v);
          }
        }
        if (!near.empty()) {
          next[i] = float(percentile(near, 0.5));
          changed = true;
        }
      }
    }
    z.swap(next);
  }
  return coverage_grid(x0, y1, cell, w, h, std::move(z));
}

void count_coverage(CoverageMap& m, const std::vector<Camera>& cameras) {
  for (int r = 0; r < m.height; ++r) {
    for (int c = 0; c < m.width; ++c) {
      const std::size_t i = m.index(c, r);
      m.count[i] = 0;
      m.gsd_m[i] = kNaN;
      if (!m.inside(i)) continue;
      const Eigen::Vector3d X(m.x_centre(c), m.y_centre(r), m.z[i]);
      for (const auto& cam : cameras) {
        const Eigen::Vector3d Xc = cam.pose.to_camera(X);
        if (Xc.z() <= 0) continue;
        const auto px = cam.project(X);
        if (!px) continue;
        const auto& k = cam.intrinsics;
        if (px->x() < -0.5 || px->y() < -0.5 || px->x() > k.width - 0.5 || px->y() > k.height - 0.5) continue;
        ++m.count[i];
        const float gsd = float(Xc.z() / std::max(k.fx, 1e-9));
        if (!std::isfinite(m.gsd_m[i]) || gsd < m.gsd_m[i]) m.gsd_m[i] = gsd;
      }
    }
  }
}

Sector sector_of(int sx, int sy) {
  STRATA_CHECK(sx >= 0 && sx < 3 && sy >= 0 && sy < 3, "sector index out of range");
  static const char* ew[3] = {"west", "", "east"};
  static const char* ns[3] = {"south", "", "north"};
  Sector s;
  if (sx == 1 && sy == 1) {
    s.name = "centre";
    return s;
  }
  if (sx != 1) s.sides.push_back(ew[sx]);
  if (sy != 1) s.sides.push_back(ns[sy]);
  if (sx != 1 && sy != 1) {
    s.name = std::string(ns[sy]) + "-" + ew[sx] + " corner";
  } else {
    s.name = s.sides.front() + " edge";
  }
  return s;
}

std::vector<CoverageShortfall> find_coverage_gaps(const CoverageMap& m, int min_photos, double min_fraction) {
  return shortfalls(
      m, min_fraction, [&](std::size_t i) { return m.count[i] < min_photos; }, [](std::size_t) { return true; });
}

std::vector<CoverageShortfall> find_low_resolution(const CoverageMap& m, double max_gsd_m, double min_fraction) {
  return shortfalls(
      m, min_fraction, [&](std::size_t i) { return m.gsd_m[i] > max_gsd_m; },
      [&](std::size_t i) { return m.count[i] > 0; });
}

std::string side_to_photograph(const CoverageShortfall& gap, const std::vector<Eigen::Vector2d>& camera_centres,
                               const Eigen::Vector2d& trench_centre) {
  if (gap.sector.sides.empty()) return "";
  auto bearing_of_side = [](const std::string& side) {  // radians from east, anticlockwise
    if (side == "east") return 0.0;
    if (side == "north") return std::numbers::pi / 2;
    if (side == "west") return std::numbers::pi;
    return -std::numbers::pi / 2;
  };
  std::string best;
  int best_count = std::numeric_limits<int>::max();
  for (const auto& side : gap.sector.sides) {
    const double b = bearing_of_side(side);
    int n = 0;
    for (const auto& c : camera_centres) {
      const Eigen::Vector2d d = c - trench_centre;
      if (d.norm() < 1e-9) continue;
      double diff = std::atan2(d.y(), d.x()) - b;
      diff = std::remainder(diff, 2 * std::numbers::pi);
      if (std::abs(diff) <= std::numbers::pi / 4) ++n;
    }
    if (n < best_count) {  // ties keep the first side listed (east/west before north/south)
      best_count = n;
      best = side;
    }
  }
  return best;
}

}  // namespace strata
