#include "texture_scene.hpp"

#include <algorithm>
#include <cmath>

namespace strata::texture_scene {
namespace {
const std::array<double, 3> kBoxColour = {30, 40, 220};
}  // namespace

std::array<double, 3> floor_colour(double x, double y) {
  return {128 + 100 * std::sin(20 * x), 128 + 100 * std::cos(17 * y), 60 + 40 * std::sin(11 * (x + y))};
}
Camera camera_at(const Eigen::Vector3d& c) {
  Camera cam;
  cam.intrinsics = {320, 240, 300, 300, 159.5, 119.5, -0.05, 0.01};
  cam.pose = Pose::look_at(c, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitY());
  return cam;
}

OrthoView render(const std::string& name, const Camera& cam) {
  OrthoView v;
  v.name = name;
  v.camera = cam;
  const Intrinsics& K = cam.intrinsics;
  v.rgb.resize(std::size_t(K.width) * K.height * 3);
  const Eigen::Vector3d C = cam.pose.centre();
  const Eigen::Vector3d lo(-kBoxHalf, -kBoxHalf, 0), hi(kBoxHalf, kBoxHalf, kBoxH);
  for (int y = 0; y < K.height; ++y) {
    for (int x = 0; x < K.width; ++x) {
      const Eigen::Vector3d d = cam.ray({double(x), double(y)});
      double t0 = 0, t1 = 1e9;
      for (int k = 0; k < 3; ++k) {
        double a = (lo[k] - C[k]) / d[k], b = (hi[k] - C[k]) / d[k];
        if (a > b) std::swap(a, b);
        t0 = std::max(t0, a);
        t1 = std::min(t1, b);
      }
      const double t_floor = -C.z() / d.z();
      std::array<double, 3> c = {0, 0, 0};
      if (t0 <= t1 && t0 < t_floor) {
        c = kBoxColour;
      } else if (t_floor > 0) {
        const Eigen::Vector3d P = C + t_floor * d;
        c = floor_colour(P.x(), P.y());
      }
      for (int k = 0; k < 3; ++k) v.rgb[(std::size_t(y) * K.width + x) * 3 + k] = std::uint8_t(std::lround(c[k]));
    }
  }
  return v;
}

DenseMesh scene_mesh() {
  DenseMesh m;
  const int n = int(std::lround(2 * kFloorHalf / kFloorStep));
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) m.vertices.emplace_back(-kFloorHalf + i * kFloorStep, -kFloorHalf + j * kFloorStep, 0);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
      m.faces.push_back({a, b, c});
      m.faces.push_back({a, c, d});
    }
  }
  // The box: top and four sides, outward normals (counter-clockwise from outside).
  auto quad = [&](Eigen::Vector3d p0, Eigen::Vector3d p1, Eigen::Vector3d p2, Eigen::Vector3d p3) {
    const int b = int(m.vertices.size());
    m.vertices.insert(m.vertices.end(), {p0, p1, p2, p3});
    m.faces.push_back({b, b + 1, b + 2});
    m.faces.push_back({b, b + 2, b + 3});
  };
  const double s = kBoxHalf, h = kBoxH;
  quad({-s, -s, h}, {s, -s, h}, {s, s, h}, {-s, s, h});
  quad({-s, -s, 0}, {s, -s, 0}, {s, -s, h}, {-s, -s, h});
  quad({s, -s, 0}, {s, s, 0}, {s, s, h}, {s, -s, h});
  quad({s, s, 0}, {-s, s, 0}, {-s, s, h}, {s, s, h});
  quad({-s, s, 0}, {-s, -s, 0}, {-s, -s, h}, {-s, s, h});
  return m;
}

}  // namespace strata::texture_scene
