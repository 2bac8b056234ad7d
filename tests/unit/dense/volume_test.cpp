// A volume computed two ways must agree (style.md "numerical cross-checks"): the
// OpenVDB level-set volume of a closed shape, the CGAL volume of the mesh extracted
// from it, and the analytic volume.
#include "core/error.hpp"
#include "dense/dense.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <numbers>

namespace strata {
namespace {

// A 5 mm voxel sphere of radius 0.2 m: level-set and marching-cubes volumes
// carry O(voxel / radius) discretisation error, about 0.5 % here.
constexpr double kRadius = 0.2;          // metres
constexpr double kVoxel = 0.005;         // metres
constexpr double kRelTolAnalytic = 0.01; // relative, voxel-grid volume vs 4/3 pi r^3
constexpr double kRelTolMesh = 0.01;     // relative, CGAL mesh volume vs OpenVDB volume
constexpr double kRelTolSimplified = 0.02;  // after edge collapse to kTargetFaces
constexpr std::size_t kTargetFaces = 3000;

std::filesystem::path write_sphere(const std::filesystem::path& path) {
  openvdb::initialize();
  auto grid = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
      static_cast<float>(kRadius), openvdb::Vec3f(0.1f, -0.2f, 0.3f), static_cast<float>(kVoxel), 3.0f);
  grid->setName("surface");
  openvdb::io::File file(path.string());
  file.write({grid});
  file.close();
  return path;
}

double signed_volume(const DenseMesh& m) {
  double v = 0;  // divergence theorem; positive when faces wind outwards
  for (const auto& f : m.faces) {
    v += m.vertices[f[0]].dot(m.vertices[f[1]].cross(m.vertices[f[2]])) / 6.0;
  }
  return v;
}

TEST(DenseVolume, OpenVdbAndCgalVolumesAgreeForSphere) {
  test::ScratchDir dir("dense_volume");
  const auto vdb = write_sphere(dir / "sphere.vdb");
  const double analytic = 4.0 / 3.0 * std::numbers::pi * kRadius * kRadius * kRadius;
  const double voxels = level_set_volume_m3(vdb);
  const DenseMesh mesh = level_set_mesh(vdb);
  ASSERT_GT(mesh.faces.size(), 1000u);
  const double cgal = closed_mesh_volume_m3(mesh);
  EXPECT_NEAR(voxels, analytic, kRelTolAnalytic * analytic);
  EXPECT_NEAR(cgal, voxels, kRelTolMesh * voxels);
  EXPECT_NEAR(cgal, analytic, kRelTolAnalytic * analytic);
  // Faces wind counter-clockwise seen from outside (normals out of the level set).
  EXPECT_NEAR(signed_volume(mesh), cgal, kRelTolMesh * cgal);

  const DenseMesh simple = simplify_mesh(mesh, kTargetFaces);
  EXPECT_LE(simple.faces.size(), kTargetFaces);
  EXPECT_GT(simple.faces.size(), kTargetFaces / 2);
  EXPECT_NEAR(closed_mesh_volume_m3(simple), analytic, kRelTolSimplified * analytic);
}

TEST(DenseVolume, OpenMeshHasNoVolume) {
  DenseMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.faces = {{0, 1, 2}};
  EXPECT_THROW(closed_mesh_volume_m3(m), ProcessingError);
}

}  // namespace
}  // namespace strata
