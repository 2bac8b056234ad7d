#pragma once
// The ray-traced test scene of the texture tests: a floor with a smooth colour
// field and a 15 cm blue box standing on it, seen by two cameras with radial
// distortion. Camera A is closer (it would win every face it sees); floor behind
// the box, hidden from A, must come from camera B.
#include "dense/dense_mesh.hpp"
#include "products/orthophoto.hpp"

#include <array>
#include <string>
#include <vector>

namespace strata::texture_scene {

inline constexpr double kFloorHalf = 0.3, kFloorStep = 0.025;  // metres
inline constexpr double kBoxHalf = 0.05, kBoxH = 0.15;         // metres, box centred on the origin
// Texel vs truth: bilinear sampling of the photo twice (photo pixels, then the
// atlas) over a field that varies by about 2 grey levels per photo pixel, plus
// 8-bit rounding of both.
inline constexpr double kColourTolerance = 6;

std::array<double, 3> floor_colour(double x, double y);
Camera camera_at(const Eigen::Vector3d& c);
// Ray-traced photo of the scene (nearest of floor and box along each pixel's ray).
OrthoView render(const std::string& name, const Camera& cam);
DenseMesh scene_mesh();

struct Scene {
  DenseMesh mesh = scene_mesh();
  std::vector<OrthoView> views = {render("A", camera_at({-0.3, 0.0, 0.6})), render("B", camera_at({0.5, 0.05, 1.2}))};
};

}  // namespace strata::texture_scene
