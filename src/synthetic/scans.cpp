#include "synthetic/scans.hpp"

#include "synthetic/noise.hpp"
#include "synthetic/render.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace strata::synthetic {
namespace {

constexpr double kStationOffset = 0.6;   // metres outside the trench edge: the tripod's legs clear the side
constexpr double kStationJitter = 0.08;  // metres, uniform, per layer (set up again each session)
constexpr double kMaxRange = 15.0;       // metres: beyond the trench, never reached inside the window
constexpr double kFloorNormalZ = 0.7;    // a hit with a steeper normal is a section face (material bands)

// Gaussian from two hashes of the ray index (Box-Muller): the same number whichever
// thread casts the ray.
double ray_normal(std::uint64_t index, std::uint32_t seed) {
  const double u1 = std::max(hash_unit(std::int64_t(index), 1, seed), 1e-300);
  const double u2 = hash_unit(std::int64_t(index), 2, seed);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2 * std::numbers::pi * u2);
}

}  // namespace

Eigen::Matrix4d ScanStation::scanner_to_site() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  m.topRightCorner<3, 1>() = origin;
  return m;
}

std::vector<ScanStation> plan_scan_stations(const Scene& scene, int layer, std::uint64_t seed) {
  const auto& o = scene.options().scans;
  Rng rng(mix64(seed ^ 0x5CA115ull) + std::uint64_t(layer) * 7919);
  const double x0 = scene.trench_x0(), x1 = scene.trench_x1(), y0 = scene.trench_y0(), y1 = scene.trench_y1();
  const double d = kStationOffset, c = kStationOffset / std::sqrt(2.0);
  const std::vector<Eigen::Vector2d> spots = {
      {0.5 * (x0 + x1), y0 - d}, {x1 + c, y1 + c}, {x0 - c, y1 + c}};
  std::vector<ScanStation> out;
  for (int k = 0; k < o.stations; ++k) {
    ScanStation s;
    const Eigen::Vector2d xy = spots[std::size_t(k)] + Eigen::Vector2d(rng.uniform(-kStationJitter, kStationJitter),
                                                                       rng.uniform(-kStationJitter, kStationJitter));
    s.origin = {xy.x(), xy.y(), scene.surface(layer).sample(xy.x(), xy.y()) + o.height_m};
    s.yaw = rng.uniform(-std::numbers::pi, std::numbers::pi);
    out.push_back(s);
  }
  return out;
}

SimulatedScan simulate_scan(const Scene& scene, int layer, const ScanStation& station, std::uint64_t seed) {
  const auto& o = scene.options().scans;
  const HeightGrid& grid = scene.surface(layer);
  const double m = o.crop_margin_m;
  const double bx0 = scene.trench_x0() - m, bx1 = scene.trench_x1() + m;
  const double by0 = scene.trench_y0() - m, by1 = scene.trench_y1() + m;
  const Eigen::Vector3d& c = station.origin;

  // The angular window that covers the box: azimuths of its corners about the
  // direction to its centre; elevations from its lowest and highest ground, seen at
  // its nearest and farthest horizontal distance.
  const double az_mid = std::atan2(0.5 * (by0 + by1) - c.y(), 0.5 * (bx0 + bx1) - c.x());
  double az_lo = 0, az_hi = 0, far = 0;
  for (const Eigen::Vector2d& corner : {Eigen::Vector2d(bx0, by0), Eigen::Vector2d(bx1, by0),
                                       Eigen::Vector2d(bx1, by1), Eigen::Vector2d(bx0, by1)}) {
    double a = std::atan2(corner.y() - c.y(), corner.x() - c.x()) - az_mid;
    a = std::remainder(a, 2 * std::numbers::pi);
    az_lo = std::min(az_lo, a);
    az_hi = std::max(az_hi, a);
    far = std::max(far, (corner - c.head<2>()).norm());
  }
  const double near = std::hypot(std::max({bx0 - c.x(), 0.0, c.x() - bx1}), std::max({by0 - c.y(), 0.0, c.y() - by1}));
  const auto [zlo_it, zhi_it] = std::minmax_element(grid.z.begin(), grid.z.end());
  const double el_lo = std::atan2(double(*zlo_it) - c.z(), std::max(near, 0.05));
  const double el_hi = std::max(std::atan2(double(*zhi_it) - c.z(), std::max(near, 0.05)),
                                std::atan2(double(*zhi_it) - c.z(), far));
  const double step = o.step_mrad * 1e-3;
  const int n_az = int(std::ceil((az_hi - az_lo) / step)) + 1;
  const int n_el = int(std::ceil((el_hi - el_lo) / step)) + 1;

  const Eigen::Matrix3d R = station.scanner_to_site().topLeftCorner<3, 3>();
  const auto seed32 = std::uint32_t(mix64(seed));
  struct Row {
    std::vector<Eigen::Vector3f> points;
    std::vector<float> intensity, range;
  };
  std::vector<Row> rows(static_cast<std::size_t>(n_el));
  tbb::parallel_for(0, n_el, [&](int e) {
    Row& row = rows[std::size_t(e)];
    const double el = el_lo + e * step;
    for (int a = 0; a < n_az; ++a) {
      const double az = az_mid + az_lo + a * step;
      const Eigen::Vector3d dir(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
      const RayHit hit = cast_ray(scene, layer, c, dir);
      if (hit.where == RayHit::Where::sky || hit.t > kMaxRange) continue;
      const Eigen::Vector3d& p = hit.point;
      if (p.x() < bx0 || p.x() > bx1 || p.y() < by0 || p.y() > by1) continue;
      const std::uint64_t index = std::uint64_t(e) * std::uint64_t(n_az) + std::uint64_t(a);
      const double r = hit.t + o.sigma_m * ray_normal(index, seed32);
      const Eigen::Vector3d noisy = c + r * dir;
      row.points.push_back((R.transpose() * (noisy - c)).cast<float>());
      // Intensity: the material's reflectance times the cosine of incidence.
      const Eigen::Vector3d n = hit.where == RayHit::Where::grid ? grid.normal(p.x(), p.y()) : Eigen::Vector3d::UnitZ();
      const Material mat = scene.material_at(p.x(), p.y(), p.z(), layer, n.z() > kFloorNormalZ);
      const Rgb rgb = scene.albedo(mat, p.x(), p.y(), step * hit.t);
      const double lum = 0.2126 * rgb.r + 0.7152 * rgb.g + 0.0722 * rgb.b;
      row.intensity.push_back(float(std::clamp(lum * std::abs(n.dot(dir)), 0.0, 1.0)));
      row.range.push_back(float(hit.t));
    }
  });
  SimulatedScan scan;
  scan.station = station;
  for (auto& row : rows) {
    scan.points.insert(scan.points.end(), row.points.begin(), row.points.end());
    scan.intensity.insert(scan.intensity.end(), row.intensity.begin(), row.intensity.end());
    scan.true_range.insert(scan.true_range.end(), row.range.begin(), row.range.end());
  }
  return scan;
}

std::vector<TargetObservation> observe_scan_targets(const Scene& scene, int layer, const ScanStation& station,
                                                    std::uint64_t seed) {
  constexpr double kMaxIncidence = 75.0 * std::numbers::pi / 180.0;  // from the print's normal (vertical)
  constexpr double kOccluderClearance = 0.01;  // metres: a hit this much short of the centre hides it
  const double sigma = scene.options().scans.target_sigma_m;
  const Eigen::Matrix3d R = station.scanner_to_site().topLeftCorner<3, 3>();
  Rng rng(mix64(seed ^ 0x7A26E75ull));
  std::vector<TargetObservation> out;
  for (const MarkerTarget& m : scene.markers()) {
    const Eigen::Vector3d d = m.centre - station.origin;
    const double range = d.norm();
    const Eigen::Vector3d dir = d / range;
    if (range > kMaxRange || std::acos(std::clamp(-dir.z(), -1.0, 1.0)) > kMaxIncidence) continue;
    const RayHit hit = cast_ray(scene, layer, station.origin, dir);
    if (hit.where != RayHit::Where::sky && hit.t < range - kOccluderClearance) continue;
    const Eigen::Vector3d noise(rng.normal(), rng.normal(), rng.normal());
    out.push_back({m.name, R.transpose() * d + sigma * noise});
  }
  return out;
}

}  // namespace strata::synthetic
