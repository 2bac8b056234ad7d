// simplify_mesh keeps what the levels of detail of `export model --lod` need: face
// counts at the target, and the vertex colours and normals of the surface, checked on
// a gently sloping grid whose colour is a known linear ramp (synthetic truth).
#include "dense/dense_mesh.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace strata {
namespace {

constexpr int kCells = 80;           // grid cells per side: 12800 faces
constexpr double kCellM = 0.01;      // metres
constexpr double kSlope = 0.1;       // dz/dx: the surface is not flat, its normal known
// The collapses stop on an edge count (about 1.5 per face, more on the border of an
// open mesh), so a level ends at or a little below its target.
constexpr double kMinShareOfTarget = 0.8;
// A coarse vertex has the mean colour of the fine vertices nearest to it (its Voronoi
// cell): centred on it inside the grid, one-sided on the border, where the mean lies up
// to about one vertex spacing inwards. At the coarsest level tested (about 10 x 10
// vertices, a spacing of a tenth of the ramp's 255 levels) that is some 25-35 levels on
// the border, a few inside.
constexpr double kColourTolerance = 40;     // grey levels (0-255), any vertex
constexpr double kMeanColourTolerance = 8;  // grey levels, averaged over the vertices
constexpr double kNormalCosine = 0.999;  // the mean of identical unit normals is that normal

double side_m() { return kCells * kCellM; }
// The colour field: red rises from west to east, green from south to north, blue fixed.
Eigen::Vector3d ramp(const Eigen::Vector3d& p) { return {255 * p.x() / side_m(), 255 * p.y() / side_m(), 64}; }
Eigen::Vector3f slope_normal() { return Eigen::Vector3f(-float(kSlope), 0, 1).normalized(); }

DenseMesh coloured_slope() {
  DenseMesh m;
  for (int j = 0; j <= kCells; ++j) {
    for (int i = 0; i <= kCells; ++i) {
      const Eigen::Vector3d p(i * kCellM, j * kCellM, kSlope * i * kCellM);
      m.vertices.push_back(p);
      m.colours.push_back(ramp(p).array().round().cast<std::uint8_t>().matrix());
      m.normals.push_back(slope_normal());
    }
  }
  const int row = kCells + 1;
  for (int j = 0; j < kCells; ++j) {
    for (int i = 0; i < kCells; ++i) {
      const int a = j * row + i;
      m.faces.push_back({a, a + 1, a + row + 1});
      m.faces.push_back({a, a + row + 1, a + row});
    }
  }
  return m;
}

TEST(Simplify, LevelsOfDetailKeepTheirFaceCountsColoursAndNormals) {
  const DenseMesh full = coloured_slope();
  for (int level = 1; level <= 3; ++level) {
    const std::size_t target = full.faces.size() >> (2 * level);  // faces / 4^level
    const DenseMesh m = simplify_mesh(full, target);
    EXPECT_LE(m.faces.size(), target) << "level " << level;
    EXPECT_GE(double(m.faces.size()), kMinShareOfTarget * double(target)) << "level " << level;
    ASSERT_EQ(m.colours.size(), m.vertices.size());
    ASSERT_EQ(m.normals.size(), m.vertices.size());
    double sum_error = 0;
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
      const double error = (m.colours[i].cast<double>() - ramp(m.vertices[i])).cwiseAbs().maxCoeff();
      EXPECT_LT(error, kColourTolerance) << "level " << level << " vertex " << i;
      sum_error += error;
      EXPECT_GT(m.normals[i].dot(slope_normal()), kNormalCosine) << "level " << level << " vertex " << i;
      EXPECT_NEAR(m.normals[i].norm(), 1.0f, 1e-5f);
    }
    EXPECT_LT(sum_error / double(m.vertices.size()), kMeanColourTolerance) << "level " << level;
  }
}

TEST(Simplify, AMeshAlreadySmallEnoughComesBackWhole) {
  const DenseMesh full = coloured_slope();
  const DenseMesh m = simplify_mesh(full, full.faces.size());
  EXPECT_EQ(m.faces, full.faces);
  EXPECT_EQ(m.colours, full.colours);
}

}  // namespace
}  // namespace strata
