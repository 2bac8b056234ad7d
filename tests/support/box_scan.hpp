#pragma once
// A simulated range scan of an analytic scene for tests (header-only): a box standing
// on the horizontal plane z = box.min.z, swept from a station on a regular grid of
// azimuth and elevation, each range with Gaussian noise. Site frame, metres.
#include <Eigen/Core>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace strata::test {

struct BoxOnPlane {
  Eigen::Vector3d min, max;  // the box; the plane is z = min.z()
  Eigen::Vector2d crop_min, crop_max;  // points kept over this XY rectangle
};

// First hit of the ray o + t d (d unit) with the box or the plane.
inline std::optional<double> box_scene_hit(const BoxOnPlane& s, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  double t0 = 0, t1 = 1e9;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(d[k]) < 1e-12) {
      if (o[k] < s.min[k] || o[k] > s.max[k]) t1 = -1;
      continue;
    }
    double a = (s.min[k] - o[k]) / d[k], b = (s.max[k] - o[k]) / d[k];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  if (t0 <= t1 && t1 > 0) return t0;
  if (d.z() < 0) return (s.min.z() - o.z()) / d.z();
  return std::nullopt;
}

// The noisy points (site frame) of rays at elevations [el0, el1) and azimuths
// [az0, az1), radians, every `step` radians.
inline std::vector<Eigen::Vector3d> box_scene_scan(const BoxOnPlane& s, const Eigen::Vector3d& station, double el0,
                                                   double el1, double az0, double az1, double step, double sigma,
                                                   unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0, sigma);
  std::vector<Eigen::Vector3d> out;
  for (double el = el0; el < el1; el += step)
    for (double az = az0; az < az1; az += step) {
      const Eigen::Vector3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
      const auto t = box_scene_hit(s, station, d);
      if (!t) continue;
      const Eigen::Vector3d p = station + *t * d;
      if (p.x() < s.crop_min.x() || p.x() > s.crop_max.x() || p.y() < s.crop_min.y() || p.y() > s.crop_max.y())
        continue;
      out.push_back(station + (*t + noise(rng)) * d);
    }
  return out;
}

// The points of a scan at `station` turned by `R` (scanner -> site: x = R s + station)
// in its scanner's frame, as XYZ text (10 um), and that pose as the 4x4 file that
// `strata import scan --transform` reads.
inline std::string scanner_frame_xyz(const std::vector<Eigen::Vector3d>& site, const Eigen::Matrix3d& R,
                                     const Eigen::Vector3d& station) {
  std::string out;
  for (const Eigen::Vector3d& p : site) {
    const Eigen::Vector3d s = R.transpose() * (p - station);
    out += fmt::format("{:.5f} {:.5f} {:.5f}\n", s.x(), s.y(), s.z());
  }
  return out;
}
inline std::string pose_file_text(const Eigen::Matrix3d& R, const Eigen::Vector3d& station) {
  std::string m = "# scanner -> site frame\n";
  for (int r = 0; r < 3; ++r)
    m += fmt::format("{:.15f} {:.15f} {:.15f} {:.15f}\n", R(r, 0), R(r, 1), R(r, 2), station[r]);
  return m + "0 0 0 1\n";
}

}  // namespace strata::test
