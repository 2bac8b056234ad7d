#include "unit/sfm/synthetic_scene.hpp"

#include <cmath>
#include <map>
#include <random>

namespace strata::test {

double ground_height(double e, double n) {
  // A gentle slope, two broad undulations and a small ridge: about +-15 cm.
  return 0.03 * e + 0.08 * std::sin(1.3 * e) * std::cos(1.7 * n) + 0.05 * std::exp(-4 * (n - 0.3) * (n - 0.3));
}

std::vector<Eigen::Vector3d> SyntheticScene::centres() const {
  std::vector<Eigen::Vector3d> c;
  for (const auto& p : poses) c.push_back(p.centre());
  return c;
}

Reconstruction SyntheticScene::truth_reconstruction() const {
  Reconstruction rec;
  CameraGroup g;
  g.intrinsics = truth;
  rec.groups = {g};
  for (std::size_t i = 0; i < poses.size(); ++i) {
    rec.images.push_back({images[i].name, 0, true, poses[i]});
  }
  std::vector<SparsePoint> pts(points.size());
  for (std::size_t p = 0; p < points.size(); ++p) pts[p].X = points[p];
  for (std::size_t i = 0; i < poses.size(); ++i) {
    for (std::size_t k = 0; k < point_of_keypoint[i].size(); ++k) {
      pts[point_of_keypoint[i][k]].track.push_back({int(i), int(k)});
    }
  }
  for (auto& p : pts) {
    if (p.track.size() >= 2) rec.points.push_back(std::move(p));
  }
  return rec;
}

SyntheticScene make_scene(const SceneOptions& o) {
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 1.0);
  SyntheticScene s;
  // A 1600 x 1200 camera, principal point 14 px / -9 px off centre, barrel distortion.
  s.truth.width = 1600;
  s.truth.height = 1200;
  s.truth.fx = s.truth.fy = 1380.0;
  s.truth.cx = 799.5 + 14.0;
  s.truth.cy = 599.5 - 9.0;
  s.truth.model = o.lens;
  switch (o.lens) {
    case CameraModel::radial:
      s.truth.k1 = -0.045;
      s.truth.k2 = 0.012;
      break;
    case CameraModel::brown:
      s.truth.k1 = -0.16;
      s.truth.k2 = 0.09;
      s.truth.k3 = -0.02;
      s.truth.p1 = 4e-4;
      s.truth.p2 = -6e-4;
      break;
    case CameraModel::fisheye:
      // The half-diagonal (1000 px) at 75 degrees off axis: f = 1000 / 1.309 rad.
      s.truth.fx = s.truth.fy = 764.0;
      s.truth.k1 = 0.04;
      s.truth.k2 = -0.01;
      s.truth.k3 = 0.003;
      s.truth.k4 = -0.0005;
      break;
  }
  CameraGroup prior;
  prior.intrinsics = s.truth;
  prior.intrinsics.fx = prior.intrinsics.fy = s.truth.fx * (1.0 + o.focal_prior_error);
  prior.intrinsics.cx = 799.5;
  prior.intrinsics.cy = 599.5;
  prior.intrinsics.k1 = prior.intrinsics.k2 = prior.intrinsics.k3 = prior.intrinsics.k4 = 0.0;
  prior.intrinsics.p1 = prior.intrinsics.p2 = 0.0;
  prior.focal_from_exif = true;
  s.groups = {prior};

  for (int p = 0; p < o.points; ++p) {
    const double e = -2.0 + 4.0 * uni(rng), n = -1.5 + 3.0 * uni(rng);
    // Stones and clods: a centimetre of roughness on the smooth surface.
    s.points.emplace_back(e, n, ground_height(e, n) + 0.01 * noise(rng));
  }
  // Cameras on a loose grid, alternating heights, aimed at points pulled towards the
  // centre (oblique views) with a random roll: varied directions make the principal
  // point and distortion observable.
  const int cols = int(std::ceil(std::sqrt(o.cameras * 4.0 / 3.0)));
  for (int c = 0; c < o.cameras; ++c) {
    const int col = c % cols, row = c / cols;
    const int rows = (o.cameras + cols - 1) / cols;
    const double e = -1.6 + 3.2 * (cols > 1 ? double(col) / (cols - 1) : 0.5) + 0.1 * noise(rng);
    const double n = -1.1 + 2.2 * (rows > 1 ? double(row) / (rows - 1) : 0.5) + 0.1 * noise(rng);
    const double h = 1.6 + 0.8 * ((c * 7) % 5) / 4.0;
    const Eigen::Vector3d centre(e, n, ground_height(e, n) + h);
    const Eigen::Vector3d target(0.45 * e + 0.2 * noise(rng), 0.45 * n + 0.2 * noise(rng), 0.0);
    const double roll = 2 * M_PI * uni(rng);
    s.poses.push_back(Pose::look_at(centre, target, Eigen::Vector3d(std::cos(roll), std::sin(roll), 0)));
    s.images.push_back({"IMG_" + std::to_string(1000 + c) + ".JPG", 0});
  }

  auto project = [&](int image, const Eigen::Vector3d& X, double sigma, Eigen::Vector2d& px) {
    const Camera cam{s.truth, s.poses[image]};
    const auto p = cam.project(X);
    if (!p) return false;
    px = *p + sigma * Eigen::Vector2d(noise(rng), noise(rng));
    return px.x() >= 0 && px.y() >= 0 && px.x() <= s.truth.width - 1 && px.y() <= s.truth.height - 1;
  };
  std::vector<std::map<int, int>> kp_of_point(o.cameras);
  s.keypoints.resize(o.cameras);
  s.point_of_keypoint.resize(o.cameras);
  for (int i = 0; i < o.cameras; ++i) {
    s.keypoints[i].image = s.images[i].name;
    for (int p = 0; p < o.points; ++p) {
      Eigen::Vector2d px;
      if (!project(i, s.points[p], o.noise_px, px)) continue;
      kp_of_point[i][p] = int(s.keypoints[i].points.size());
      s.keypoints[i].points.push_back(px);
      s.point_of_keypoint[i].push_back(p);
    }
  }
  for (int a = 0; a < o.cameras; ++a) {
    for (int b = a + 1; b < o.cameras; ++b) {
      PairMatches pm;
      pm.image_a = a;
      pm.image_b = b;
      pm.model = TwoViewModel::essential;
      for (const auto& [p, ka] : kp_of_point[a]) {
        const auto it = kp_of_point[b].find(p);
        if (it != kp_of_point[b].end()) pm.matches.emplace_back(ka, it->second);
      }
      if (pm.matches.size() < 30) continue;
      const int wrong = int(std::lround(o.outlier_fraction * double(pm.matches.size())));
      const int na = int(s.keypoints[a].points.size()), nb = int(s.keypoints[b].points.size());
      for (int w = 0; w < wrong; ++w) {
        pm.matches.emplace_back(int(uni(rng) * na) % na, int(uni(rng) * nb) % nb);
      }
      s.matches.push_back(std::move(pm));
    }
  }
  for (const auto& m : o.markers) {
    MarkerConstraint mc;
    mc.name = m.name;
    mc.position = Eigen::Vector3d(m.en.x(), m.en.y(), ground_height(m.en.x(), m.en.y()));
    mc.sigma = Eigen::Vector3d::Constant(0.002);
    mc.control = m.control;
    s.markers.push_back(mc);
    for (int i = 0; i < o.cameras; ++i) {
      Eigen::Vector2d px;
      if (project(i, mc.position, o.marker_noise_px, px)) {
        s.marker_observations.push_back({m.name, i, px});
      }
    }
  }
  return s;
}

}  // namespace strata::test
