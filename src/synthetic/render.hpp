#pragma once
// Rendering the synthetic scene through the shared camera model (internal).
//
// Each layer's surface is a height field; a pixel's ray is intersected with it by
// a two-level DDA (16 x 16-cell tiles with their maximum height, then cells with
// the exact bilinear surface), which gets occlusion by trench sides, pit edges and
// stones right. Beyond the fine grid the ground is analytic. Floors are shaded
// from a baked, mip-mapped radiance texture; steep faces (sections, stone sides)
// and the printed targets are evaluated per ray. Pixels on depth edges get extra
// rays (adaptive supersampling); textures are band-limited to the pixel footprint.
#include "geometry/camera.hpp"
#include "synthetic/scene.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <vector>

namespace strata::synthetic {

// Light of one recording session (lighting differs a little between stages).
struct Lighting {
  Eigen::Vector3d sun = Eigen::Vector3d(0.3, 0.2, 0.93).normalized();  // unit, towards the sun
  Rgb sun_colour{0.55f, 0.52f, 0.47f};  // irradiance factor of direct light on a facing surface
  Rgb sky_colour{0.62f, 0.64f, 0.68f};  // irradiance factor of the open sky on a horizontal surface
};

// Linear radiance of a surface with normal n (unit) and ambient occlusion ao (0..1).
Rgb shade(const Lighting& light, const Eigen::Vector3d& n, double ao);

// A layer's floors, lit and baked, plus its ambient-occlusion field.
class LayerTexture {
 public:
  LayerTexture(const Scene& scene, int layer, const Lighting& light, double texel,
               const LayerTexture* ground = nullptr);
  Rgb sample(double x, double y, double footprint) const;  // linear radiance
  double ao(double x, double y) const;                     // 0..1
  // Unlit reflectance of layer 0 (re-used outside the trench by later layers).
  const std::vector<std::uint8_t>& albedo() const { return albedo_; }

 private:
  struct Level {
    int nx = 0, ny = 0;
    double texel = 0;                // metres
    std::vector<std::uint8_t> rgb;   // sRGB-encoded radiance, interleaved
  };
  Rgb bilinear(const Level& level, double x, double y) const;

  double x0_ = 0, y0_ = 0;           // metres, site frame: corner of texel (0, 0)
  std::vector<Level> levels_;
  std::vector<std::uint8_t> albedo_; // level-0 reflectance, sRGB-encoded
  double ao_x0_ = 0, ao_y0_ = 0, ao_cell_ = 0;
  int ao_nx_ = 0, ao_ny_ = 0;
  std::vector<float> ao_;
};

struct RayHit {
  enum class Where { sky, grid, outer } where = Where::sky;
  double t = 0;                      // metres along the unit ray
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
};
// First intersection of the ray origin + t * dir (dir unit) with layer `layer`.
RayHit cast_ray(const Scene& scene, int layer, const Eigen::Vector3d& origin,
                const Eigen::Vector3d& dir);

struct RenderSettings {
  int edge_samples = 4;  // extra rays on depth-edge pixels
  // A painted disc for tests: the renderer shows it where the surface point is.
  struct Spot {
    Eigen::Vector2d centre;  // metres, site frame (x, y)
    double radius = 0.01;    // metres
    Rgb reflectance{0.9f, 0.05f, 0.05f};
  };
  std::optional<Spot> spot;
};

struct LinearImage {
  int width = 0, height = 0;
  std::vector<float> rgb;  // linear radiance, interleaved, row-major
};

LinearImage render_view(const Scene& scene, int layer, const LayerTexture& texture,
                        const Lighting& light, const Camera& camera,
                        const RenderSettings& settings);

}  // namespace strata::synthetic
