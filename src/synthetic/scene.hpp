#pragma once
// The synthetic excavation as geometry and materials (internal to strata_synthetic).
//
// Frame: the site frame of docs/design.md, i.e. CRS coordinates minus the site
// origin, metres, z up. Geometry is a stack of smooth interfaces between deposits
// (B_0 = original ground, B_j = bottom of unit j), a pit cut, and a stone wall.
// Each recorded layer k (0 = original surface) is a height field on a fine grid;
// inside the trench it is the top of unit k+1, outside it stays the ground.
#include "synthetic/synthetic.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace strata::synthetic {

struct Rgb {
  float r = 0, g = 0, b = 0;
  Rgb operator*(float s) const { return {r * s, g * s, b * s}; }
  Rgb operator*(const Rgb& o) const { return {r * o.r, g * o.g, b * o.b}; }
  Rgb operator+(const Rgb& o) const { return {r + o.r, g + o.g, b + o.b}; }
};
inline Rgb lerp(const Rgb& a, const Rgb& b, double t) {
  const float f = float(t);
  return {a.r + (b.r - a.r) * f, a.g + (b.g - a.g) * f, a.b + (b.b - a.b) * f};
}
// sRGB 8-bit triple (how colours are specified) to linear reflectance.
Rgb from_srgb8(int r, int g, int b);

// Heights on a regular grid of nodes; bilinear between nodes. The rendered surface
// and the truth rasters both sample it, so they agree exactly.
struct HeightGrid {
  double x0 = 0, y0 = 0;  // metres, site frame, node (0, 0)
  double cell = 0;        // metres between nodes
  int nx = 0, ny = 0;
  std::vector<float> z;   // metres, site frame, row-major (j * nx + i), j along +y

  float node(int i, int j) const { return z[std::size_t(j) * std::size_t(nx) + std::size_t(i)]; }
  double x1() const { return x0 + (nx - 1) * cell; }
  double y1() const { return y0 + (ny - 1) * cell; }
  bool contains(double x, double y) const { return x >= x0 && x <= x1() && y >= y0 && y <= y1(); }
  double sample(double x, double y) const;                   // bilinear, clamped at the edge
  Eigen::Vector2d gradient(double x, double y) const;        // central differences, one cell
  Eigen::Vector3d normal(double x, double y) const;
};

struct MarkerTarget {
  int id = 0;                 // ArUco DICT_4X4_50 id
  std::string name;           // "GCP<id>"
  bool check = false;         // check point (not used for control)
  Eigen::Vector3d centre;     // metres, site frame: the printed square's centre on the ground
  double yaw = 0;             // radians, rotation of the print about the vertical
  double size = 0;            // metres, printed square including the white border
  std::array<std::uint8_t, 64> white{};  // 8 x 8 cells, row 0 = marker top, 1 = white
};

struct Stone {
  Eigen::Vector2d c;          // metres, site frame
  double a = 0, b = 0;        // metres, horizontal semi-axes
  double yaw = 0;             // radians
  double base = 0, top = 0;   // metres, site frame
  double tint = 1;            // brightness factor of this block
  double tilt = 0;            // -1..1: slope of its top along its length
  double cos_yaw = 1, sin_yaw = 0;
};

struct Pit {
  Eigen::Vector2d c;          // metres, site frame
  double a = 0, b = 0;        // metres, semi-axes at the rim
  double yaw = 0;             // radians
  double depth = 0;           // metres below the surface it is cut from
  int cut_from = 0;           // interface index: cut from the top of unit cut_from+1
  double cos_yaw = 1, sin_yaw = 0;
};

struct UnitRecord {
  std::string code, type, description;
};
struct RelationRecord {
  std::string a, relation, b;
};

// What a surface point is made of.
struct Material {
  int kind = 0;   // 0 = ground surface, 1..K+1 = deposit unit index, K+2 = stone
  int stone = -1; // index into stones() when kind is stone
};

class Scene {
 public:
  explicit Scene(const SyntheticExcavationOptions& options);

  int stages() const { return stages_; }
  int layers() const { return stages_ + 1; }
  int stone_kind() const { return stages_ + 2; }
  const SyntheticExcavationOptions& options() const { return options_; }

  // Trench footprint, metres, site frame.
  double trench_x0() const { return tx0_; }
  double trench_y0() const { return ty0_; }
  double trench_x1() const { return tx1_; }
  double trench_y1() const { return ty1_; }

  const HeightGrid& surface(int layer) const { return surfaces_.at(std::size_t(layer)); }
  // Maximum-height pyramid of a layer: level l holds the highest node of each
  // block of 4^l x 4^l cells (level 0: the cells, max unused). Lets the ray marcher skip empty space.
  struct MaxLevel {
    int block = 1;       // cells per block side
    int nx = 0, ny = 0;  // blocks
    std::vector<float> max;
  };
  const std::vector<MaxLevel>& max_pyramid(int layer) const { return pyramids_.at(std::size_t(layer)); }
  float surface_max(int layer) const { return surface_max_.at(std::size_t(layer)); }
  // Upper bound of |grad ground_smooth|, for conservative ray marching.
  double ground_slope_bound() const { return ground_slope_bound_; }

  // The ground beyond the fine grid: smooth, analytic (no micro-relief).
  double ground_smooth(double x, double y) const;
  // Interface j between unit j and j+1 (0 = original ground), smooth, with the pit.
  double interface_smooth(int j, double x, double y) const;
  // Height of the stone wall at (x, y), -infinity where there is no stone.
  double stone_height(double x, double y, int* which = nullptr) const;
  // Trench weight: 1 inside (dug), 0 outside, a 2-3 cm ramp forms the steep side.
  double trench_weight(double x, double y) const;

  // Material of the point (x, y, z) on layer `layer`. `floor` is true for
  // near-horizontal surfaces (the exposed unit) and false for sections (walls),
  // where the deposits show in bands.
  Material material_at(double x, double y, double z, int layer, bool floor) const;
  // Linear reflectance of material `m` at texture coordinates (u, v) in metres,
  // band-limited to `footprint` metres.
  Rgb albedo(const Material& m, double u, double v, double footprint) const;
  // The printed target under (x, y), if any: how much of the footprint it covers
  // and its mean reflectance there (grey: white paper, black ink).
  struct Print {
    double coverage = 0;     // 0..1
    double reflectance = 0;  // linear, over the covered part
  };
  Print marker_print(double x, double y, double footprint) const;

  const std::vector<MarkerTarget>& markers() const { return markers_; }
  const std::vector<Stone>& stones() const { return stones_; }
  const Pit& pit() const { return pit_; }
  const std::vector<UnitRecord>& units() const { return units_; }
  const std::vector<RelationRecord>& relations() const { return relations_; }
  // Code of the unit whose top layer k is (layer 0 -> first unit).
  std::string layer_unit_code(int layer) const;

  std::uint32_t seed32() const { return seed32_; }

  static constexpr double kNoHeight = -std::numeric_limits<double>::infinity();

 private:
  double thickness(int unit, double x, double y) const;  // metres, smooth, unit >= 1
  double micro_relief(int surface, double x, double y) const;
  double pit_profile(double x, double y) const;          // metres of depth, 0 outside
  void layout(std::uint64_t seed);
  void build_surfaces();
  void build_records();

  SyntheticExcavationOptions options_;
  int stages_ = 0;
  std::uint32_t seed32_ = 0;
  double tx0_ = 0, ty0_ = 0, tx1_ = 0, ty1_ = 0;

  // Ground: base height, plane slope, undulations (amplitude, kx, ky, phase).
  double g0_ = 0, gsx_ = 0, gsy_ = 0;
  std::vector<std::array<double, 4>> ground_waves_;
  // Per removed unit: mean level and waves of the thickness field.
  std::vector<double> unit_mean_;
  std::vector<std::vector<std::array<double, 4>>> unit_waves_;
  // Trench edge wiggle seeds.
  std::uint32_t edge_seed_ = 0;

  std::vector<MarkerTarget> markers_;
  std::vector<Stone> stones_;
  Pit pit_;
  std::vector<HeightGrid> surfaces_;
  std::vector<std::vector<MaxLevel>> pyramids_;
  std::vector<float> surface_max_;
  double ground_slope_bound_ = 0;
  std::vector<UnitRecord> units_;
  std::vector<RelationRecord> relations_;
};

}  // namespace strata::synthetic
