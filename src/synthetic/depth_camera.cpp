#include "synthetic/depth_camera.hpp"

#include "synthetic/noise.hpp"
#include "synthetic/render.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace strata::synthetic {
namespace {

constexpr double kTwoPi = 2 * std::numbers::pi;
// The hand's wobble: a few slow oscillations per loop, different on each axis.
constexpr double kWobblePositionM = 0.03;  // metres, amplitude of the camera's sway
constexpr double kWobbleAimM = 0.08;       // metres, amplitude of the aim point's wander on the floor
constexpr double kWobbleRollRad = 0.05;    // radians (3 degrees), amplitude of the roll
constexpr double kPathExponent = 6.0;  // of the superellipse the path follows round the trench
constexpr double kFloorNormalZ = 0.7;  // a hit with a steeper normal is a section face (material bands)

double pixel_normal(std::uint64_t index, std::uint32_t seed) {
  const double u1 = std::max(hash_unit(std::int64_t(index), 1, seed), 1e-300);
  const double u2 = hash_unit(std::int64_t(index), 2, seed);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(kTwoPi * u2);
}

// Camera -> site rotation looking along `forward` with the image's x axis level,
// then rolled about the optical axis.
Eigen::Matrix3d look_rotation(const Eigen::Vector3d& forward, double roll) {
  const Eigen::Vector3d z = forward.normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R << x, y, z;
  return R * Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

std::uint8_t to_srgb8(double linear) {
  const double c = std::clamp(linear, 0.0, 1.0);
  const double s = c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1 / 2.4) - 0.055;
  return std::uint8_t(std::lround(255.0 * s));
}

}  // namespace

std::vector<DepthFramePlan> plan_depth_sequence(const Scene& scene, int layer, std::uint64_t seed) {
  const auto& o = scene.options().depth;
  Rng rng(mix64(seed ^ 0xDE7A5EAull) + std::uint64_t(layer) * 7927);
  const Eigen::Vector2d centre(0.5 * (scene.trench_x0() + scene.trench_x1()),
                               0.5 * (scene.trench_y0() + scene.trench_y1()));
  const double a = 0.5 * (scene.trench_x1() - scene.trench_x0()) + o.edge_offset_m;
  const double b = 0.5 * (scene.trench_y1() - scene.trench_y0()) + o.edge_offset_m;
  const double start = rng.uniform(0, kTwoPi);
  // Wobble frequencies (cycles per loop) and phases, one per axis.
  double freq[6], phase[6];
  for (int k = 0; k < 6; ++k) {
    freq[k] = rng.uniform(4, 9);
    phase[k] = rng.uniform(0, kTwoPi);
  }
  const auto wobble = [&](int k, double s) { return std::sin(kTwoPi * freq[k] * s + phase[k]); };
  const HeightGrid& surface = scene.surface(layer);
  const double floor_z = surface.sample(centre.x(), centre.y());

  std::vector<DepthFramePlan> plan(std::size_t(o.frames));
  for (int i = 0; i < o.frames; ++i) {
    const double s = double(i) / o.frames;  // share of the loop
    const double theta = start + kTwoPi * s;
    // A superellipse |x/a|^p + |y/b|^p = 1 (p = kPathExponent): a rounded rectangle
    // that stays outside the trench at its corners, where an ellipse through the
    // middles of the sides would cut across them.
    auto bend = [](double v) { return std::copysign(std::pow(std::abs(v), 2.0 / kPathExponent), v); };
    const Eigen::Vector2d offset(a * bend(std::cos(theta)), b * bend(std::sin(theta)));
    Eigen::Vector2d xy = centre + offset;
    xy += kWobblePositionM * Eigen::Vector2d(wobble(0, s), wobble(1, s));
    const Eigen::Vector3d c(xy.x(), xy.y(), surface.sample(xy.x(), xy.y()) + o.height_m + kWobblePositionM * wobble(2, s));
    const Eigen::Vector2d aim_xy = centre + o.aim_share * offset + kWobbleAimM * Eigen::Vector2d(wobble(3, s), wobble(4, s));
    const Eigen::Vector3d aim(aim_xy.x(), aim_xy.y(), floor_z);
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = look_rotation(aim - c, kWobbleRollRad * wobble(5, s));
    pose.translation() = c;
    plan[std::size_t(i)].true_pose = pose;
  }

  // The recorded poses: the true motion from the previous frame, then an error of
  // the device's tracking in the camera frame (a random walk, and a bias of the
  // rotation about the image's vertical axis, as from a gyroscope's).
  const double sr = 1e-3 * o.drift_rotation_mrad, st = o.drift_translation_m, bias = 1e-3 * o.drift_bias_mrad;
  plan[0].recorded_pose = plan[0].true_pose;
  for (std::size_t i = 1; i < plan.size(); ++i) {
    const Eigen::Isometry3d motion = plan[i - 1].true_pose.inverse() * plan[i].true_pose;
    const Eigen::Vector3d w(sr * rng.normal(), sr * rng.normal() + bias, sr * rng.normal());
    Eigen::Isometry3d error = Eigen::Isometry3d::Identity();
    if (w.norm() > 0) error.linear() = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
    error.translation() = Eigen::Vector3d(st * rng.normal(), st * rng.normal(), st * rng.normal());
    plan[i].recorded_pose = plan[i - 1].recorded_pose * motion * error;
  }
  return plan;
}

DepthFrame render_depth_frame(const Scene& scene, int layer, const Eigen::Isometry3d& pose, std::uint64_t seed) {
  const auto& o = scene.options().depth;
  const int w = o.width, h = o.height;
  const double f = o.focal_px, cx = 0.5 * (w - 1), cy = 0.5 * (h - 1);
  const HeightGrid& grid = scene.surface(layer);
  const auto seed32 = std::uint32_t(mix64(seed));
  const Eigen::Matrix3d R = pose.linear();
  const Eigen::Vector3d c = pose.translation();
  DepthFrame out;
  out.depth_mm.assign(std::size_t(w) * std::size_t(h), 0);
  out.rgb.assign(3 * std::size_t(w) * std::size_t(h), 0);
  std::vector<std::int64_t> valid(std::size_t(h), 0);
  tbb::parallel_for(0, h, [&](int v) {
    for (int u = 0; u < w; ++u) {
      const Eigen::Vector3d ray_cam((u - cx) / f, (v - cy) / f, 1.0);
      const double len = ray_cam.norm();
      const Eigen::Vector3d dir = R * ray_cam / len;
      const RayHit hit = cast_ray(scene, layer, c, dir);
      if (hit.where == RayHit::Where::sky) continue;
      const std::size_t index = std::size_t(v) * std::size_t(w) + std::size_t(u);
      const double z = hit.t / len;  // depth along the optical axis, metres
      const double noisy = z + o.noise_k * z * z * pixel_normal(index, seed32);
      if (noisy < o.min_depth_m || noisy > o.max_depth_m) continue;
      out.depth_mm[index] = std::uint16_t(std::clamp(std::lround(1000.0 * noisy), 1L, 65535L));
      ++valid[std::size_t(v)];
      const Eigen::Vector3d& p = hit.point;
      const Eigen::Vector3d n = hit.where == RayHit::Where::grid ? grid.normal(p.x(), p.y()) : Eigen::Vector3d::UnitZ();
      const Material mat = scene.material_at(p.x(), p.y(), p.z(), layer, n.z() > kFloorNormalZ);
      Rgb rgb = scene.albedo(mat, p.x(), p.y(), hit.t / f);
      // The printed targets on the ground, drawn as the photo renderer draws them
      // (render.cpp), unlit as the rest of the colour frame.
      if (hit.where == RayHit::Where::grid) {
        const Scene::Print print = scene.marker_print(p.x(), p.y(), hit.t / f);
        if (print.coverage > 0) rgb = lerp(rgb, Rgb{1, 1, 1} * float(print.reflectance), print.coverage);
      }
      out.rgb[3 * index] = to_srgb8(rgb.r);
      out.rgb[3 * index + 1] = to_srgb8(rgb.g);
      out.rgb[3 * index + 2] = to_srgb8(rgb.b);
    }
  });
  for (auto n : valid) out.valid += n;
  return out;
}

}  // namespace strata::synthetic
