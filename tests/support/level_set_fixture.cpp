#include "level_set_fixture.hpp"

#include <openvdb/openvdb.h>

#include <cmath>

namespace strata::test {
namespace {

// An empty level set grid as the fusion makes one; `fill` sets its voxels.
void write_grid(const std::filesystem::path& vdb, double voxel_m, double truncation_m,
                const Eigen::Vector3d& site_origin,
                const std::function<void(openvdb::FloatGrid::Accessor&)>& fill) {
  openvdb::initialize();
  auto grid = openvdb::FloatGrid::create(float(truncation_m));
  grid->setTransform(openvdb::math::Transform::createLinearTransform(voxel_m));
  grid->setGridClass(openvdb::GRID_LEVEL_SET);
  grid->setName("surface");
  auto acc = grid->getAccessor();
  fill(acc);
  grid->insertMeta("site_origin_e", openvdb::DoubleMetadata(site_origin.x()));
  grid->insertMeta("site_origin_n", openvdb::DoubleMetadata(site_origin.y()));
  grid->insertMeta("site_origin_z", openvdb::DoubleMetadata(site_origin.z()));
  grid->insertMeta("crs", openvdb::StringMetadata("EPSG:32636"));
  openvdb::io::File file(vdb.string());
  file.write({grid});
  file.close();
}

}  // namespace

void write_height_field_level_set(const std::filesystem::path& vdb, const std::function<double(double, double)>& h,
                                  double x0, double y0, double x1, double y1, double voxel_m, double truncation_m,
                                  const Eigen::Vector3d& site_origin) {
  write_grid(vdb, voxel_m, truncation_m, site_origin, [&](openvdb::FloatGrid::Accessor& acc) {
  const int i0 = int(std::floor(x0 / voxel_m)), i1 = int(std::ceil(x1 / voxel_m));
  const int j0 = int(std::floor(y0 / voxel_m)), j1 = int(std::ceil(y1 / voxel_m));
  for (int j = j0; j <= j1; ++j) {
    for (int i = i0; i <= i1; ++i) {
      const double z = h(i * voxel_m, j * voxel_m);
      const int k0 = int(std::floor((z - truncation_m) / voxel_m)), k1 = int(std::ceil((z + truncation_m) / voxel_m));
      for (int k = k0; k <= k1; ++k) {
        const double d = k * voxel_m - z;  // > 0 above the surface (outside)
        if (std::abs(d) >= truncation_m) continue;
        acc.setValue(openvdb::Coord(i, j, k), float(d));
      }
    }
  }
  });
}

void write_level_set(const std::filesystem::path& vdb, const std::function<double(double, double, double)>& sdf,
                     const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double voxel_m, double truncation_m,
                     const Eigen::Vector3d& site_origin) {
  write_grid(vdb, voxel_m, truncation_m, site_origin, [&](openvdb::FloatGrid::Accessor& acc) {
    const Eigen::Vector3i a = (lo / voxel_m).array().floor().cast<int>(), b = (hi / voxel_m).array().ceil().cast<int>();
    for (int i = a.x(); i <= b.x(); ++i)
      for (int j = a.y(); j <= b.y(); ++j)
        for (int k = a.z(); k <= b.z(); ++k) {
          const double d = sdf(i * voxel_m, j * voxel_m, k * voxel_m);
          if (std::abs(d) < truncation_m) acc.setValue(openvdb::Coord(i, j, k), float(d));
        }
  });
}

}  // namespace strata::test
