#include "level_set_fixture.hpp"

#include <openvdb/openvdb.h>

#include <cmath>

namespace strata::test {

void write_height_field_level_set(const std::filesystem::path& vdb, const std::function<double(double, double)>& h,
                                  double x0, double y0, double x1, double y1, double voxel_m, double truncation_m,
                                  const Eigen::Vector3d& site_origin) {
  openvdb::initialize();
  auto grid = openvdb::FloatGrid::create(float(truncation_m));
  grid->setTransform(openvdb::math::Transform::createLinearTransform(voxel_m));
  grid->setGridClass(openvdb::GRID_LEVEL_SET);
  grid->setName("surface");
  auto acc = grid->getAccessor();
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
  grid->insertMeta("site_origin_e", openvdb::DoubleMetadata(site_origin.x()));
  grid->insertMeta("site_origin_n", openvdb::DoubleMetadata(site_origin.y()));
  grid->insertMeta("site_origin_z", openvdb::DoubleMetadata(site_origin.z()));
  grid->insertMeta("crs", openvdb::StringMetadata("EPSG:32636"));
  openvdb::io::File file(vdb.string());
  file.write({grid});
  file.close();
}

}  // namespace strata::test
