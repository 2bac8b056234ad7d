#include "synthetic/photo_set.hpp"

#include "synthetic/noise.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace strata::synthetic {
namespace {

constexpr double kPi = 3.141592653589793;
constexpr double kDeg = kPi / 180.0;
constexpr double kMaxObliqueTilt = 55 * kDeg;  // from nadir: still sees the floor well
constexpr double kObliqueShare = 0.6;          // share of oblique photos in a set

Pose with_roll(const Pose& pose, double roll) {
  Eigen::Matrix3d Rz;
  Rz << std::cos(roll), -std::sin(roll), 0, std::sin(roll), std::cos(roll), 0, 0, 0, 1;
  return Pose::from_centre(Rz * pose.R, pose.centre());
}

}  // namespace

Intrinsics make_intrinsics(const SyntheticExcavationOptions& options) {
  Rng rng(options.seed ^ 0xCA3E7Aull);
  Intrinsics k;
  k.width = options.photos.width;
  k.height = options.photos.height;
  k.fx = k.fy = options.photos.focal_ratio * k.width;
  // Principal point 0.6-1.5 % of the width off the image centre, in a random direction.
  const double ang = rng.uniform(0, 2 * kPi), off = rng.uniform(0.006, 0.015) * k.width;
  k.cx = 0.5 * (k.width - 1) + off * std::cos(ang);
  k.cy = 0.5 * (k.height - 1) + off * std::sin(ang);
  using Lens = SyntheticExcavationOptions::Photos::Lens;
  switch (options.photos.lens) {
    case Lens::radial:
      k.model = CameraModel::radial;
      k.k1 = rng.uniform(-0.10, -0.05);  // barrel, typical of a 20-24 mm lens on APS-C
      k.k2 = rng.uniform(0.01, 0.04);
      break;
    case Lens::brown: {
      // A wide DSLR zoom at its short end (16-18 mm on APS-C): strong barrel, and a
      // slightly decentred element group (tangential terms of 1e-4..1e-3, of either sign).
      k.model = CameraModel::brown;
      k.k1 = rng.uniform(-0.20, -0.12);
      k.k2 = rng.uniform(0.05, 0.12);
      k.k3 = rng.uniform(-0.03, 0.0);
      const auto decentring = [&rng] { return (rng.uniform() < 0.5 ? -1 : 1) * rng.uniform(1e-4, 1e-3); };
      k.p1 = decentring();
      k.p2 = decentring();
      break;
    }
    case Lens::fisheye: {
      // An action camera: equidistant with a mild polynomial, the half-diagonal at
      // half of fisheye_diagonal_deg off the axis (f = r_corner / theta_d).
      k.model = CameraModel::fisheye;
      k.k1 = rng.uniform(0.02, 0.06);
      k.k2 = rng.uniform(-0.02, 0.0);
      k.k3 = rng.uniform(0.0, 0.005);
      k.k4 = rng.uniform(-0.001, 0.0);
      const double theta = 0.5 * options.photos.fisheye_diagonal_deg * kDeg, t2 = theta * theta;
      const double theta_d = theta * (1 + t2 * (k.k1 + t2 * (k.k2 + t2 * (k.k3 + t2 * k.k4))));
      k.fx = k.fy = 0.5 * std::hypot(double(k.width), double(k.height)) / theta_d;
      break;
    }
  }
  return k;
}

Lighting session_lighting(const Scene& scene, int layer) {
  Rng rng(scene.options().seed * 7919 + std::uint64_t(layer) * 104729 + 17);
  Lighting l;
  const double az = rng.uniform(0, 2 * kPi), el = rng.uniform(35, 65) * kDeg;
  l.sun = Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
  const double sun = rng.uniform(0.3, 0.6), sky = rng.uniform(0.55, 0.75), warm = rng.uniform(-1, 1);
  l.sun_colour = Rgb{float(sun * (1 + 0.05 * warm)), float(sun), float(sun * (1 - 0.08 * warm))};
  l.sky_colour = Rgb{float(sky * (1 - 0.03 * warm)), float(sky), float(sky * (1 + 0.05 * warm))};
  return l;
}

std::string session_time(int layer, int seconds_after_start) {
  // Sessions two days apart from 10 June 2024, starting at 09:00 plus 25 min per layer.
  const int day = 10 + 2 * layer;
  long s = 9 * 3600 + 25 * 60 * layer + seconds_after_start;
  return fmt::format("2024-06-{:02d}T{:02d}:{:02d}:{:02d}", day, s / 3600, (s / 60) % 60, s % 60);
}

std::vector<PlannedPhoto> plan_photos(const Scene& scene, int layer, const Intrinsics& intrinsics) {
  Rng rng(scene.options().seed * 31337 + std::uint64_t(layer) * 65537 + 5);
  const HeightGrid& surface = scene.surface(layer);
  const int n = scene.options().photos.per_layer;
  const int n_oblique = std::clamp(int(std::lround(kObliqueShare * n)), 1, n);
  const int n_vertical = n - n_oblique;
  const double x0 = scene.trench_x0(), y0 = scene.trench_y0(), x1 = scene.trench_x1(), y1 = scene.trench_y1();
  const double se = x1 - x0, sn = y1 - y0;
  std::vector<PlannedPhoto> photos;
  int clock = 0;
  auto add = [&](const Pose& pose, bool oblique) {
    PlannedPhoto p;
    p.name = fmt::format("L{}_{:04d}.jpg", layer + 1, int(photos.size()) + 1);
    p.camera = Camera{intrinsics, pose};
    p.seconds_after_start = clock;
    p.oblique = oblique;
    clock += rng.uniform() < 0.5 ? 1 : 2;  // a second or two between shots
    photos.push_back(p);
  };

  // Oblique: walking around the trench at 0.3-0.7 m from its edge, eye height.
  const double phase = rng.uniform();
  for (int i = 0; i < n_oblique; ++i) {
    const double off = rng.uniform(0.3, 0.7);
    const double w = se + 2 * off, h = sn + 2 * off, perimeter = 2 * (w + h);
    double s = std::fmod((i + phase + rng.uniform(-0.2, 0.2)) / n_oblique + 1.0, 1.0) * perimeter;
    Eigen::Vector2d c;
    if (s < w) c = {x0 - off + s, y0 - off};
    else if ((s -= w) < h) c = {x1 + off, y0 - off + s};
    else if ((s -= h) < w) c = {x1 + off - s, y1 + off};
    else c = {x0 - off, y1 + off - (s - w)};
    const Eigen::Vector3d centre(c.x(), c.y(), scene.ground_smooth(c.x(), c.y()) + rng.uniform(1.45, 1.7));
    // Aim beyond the trench centre: the near floor fills the bottom of the frame,
    // the far side and the targets around it the top.
    const Eigen::Vector2d mid(0.5 * (x0 + x1), 0.5 * (y0 + y1));
    const Eigen::Vector2d away = (mid - c).normalized(), side(-away.y(), away.x());
    Eigen::Vector2d t = mid + away * rng.uniform(0.0, 0.3) * std::min(se, sn) + side * rng.uniform(-0.2, 0.2) * se;
    Eigen::Vector3d target(t.x(), t.y(), surface.sample(t.x(), t.y()));
    // Not flatter than kMaxObliqueTilt from nadir: pull the target towards the camera.
    for (int it = 0; it < 20; ++it) {
      const double hd = (target.head<2>() - centre.head<2>()).norm(), dz = centre.z() - target.z();
      if (std::atan2(hd, dz) <= kMaxObliqueTilt) break;
      t = centre.head<2>() + 0.85 * (t - centre.head<2>());
      target = {t.x(), t.y(), surface.sample(t.x(), t.y())};
    }
    add(with_roll(Pose::look_at(centre, target), rng.uniform(-4, 4) * kDeg), true);
  }

  // Near-vertical: a serpentine over the trench, two rows, photographer facing
  // along the trench, 2-14 degrees off nadir.
  const int rows = std::min(2, n_vertical), cols = rows > 0 ? (n_vertical + rows - 1) / rows : 0;
  for (int i = 0; i < n_vertical; ++i) {
    const int r = i / std::max(cols, 1), cc = i % std::max(cols, 1);
    const int col = (r % 2 == 0) ? cc : cols - 1 - cc;
    const double x = x0 + se * (col + 0.5) / cols + rng.uniform(-0.1, 0.1);
    const double y = y0 + sn * (r + 0.5) / rows + rng.uniform(-0.1, 0.1);
    const Eigen::Vector3d centre(x, y, surface.sample(x, y) + rng.uniform(1.5, 2.0));
    const double tilt = rng.uniform(2, 14) * kDeg, az = rng.uniform(0, 2 * kPi);
    const Eigen::Vector3d dir(std::sin(tilt) * std::cos(az), std::sin(tilt) * std::sin(az), -std::cos(tilt));
    const double heading = (r % 2 == 0 ? 0.0 : kPi) + rng.uniform(-10, 10) * kDeg;
    const Eigen::Vector3d up(std::cos(heading), std::sin(heading), 0.0);
    add(Pose::look_at(centre, centre + dir, up), false);
  }
  return photos;
}

}  // namespace strata::synthetic
