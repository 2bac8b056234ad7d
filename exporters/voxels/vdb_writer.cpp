// writer.vdb: the voxel model's grids and file. The only translation unit of the
// exporters that includes OpenVDB.
#include "exporters/voxels/vdb_writer.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/vdb_uuid.hpp"

#include <fmt/format.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Prune.h>

#include <cmath>

namespace strata {
namespace fs = std::filesystem;
namespace {

// Fractions this close to 1 are stored as 1 so that interior blocks prune to tiles.
constexpr float kPruneTolerance = 1e-6f;

openvdb::math::Transform::Ptr voxel_transform(double h, const std::optional<Eigen::Vector2d>& offset) {
  openvdb::initialize();  // once per process; later calls return at once
  openvdb::math::Transform::Ptr transform = openvdb::math::Transform::createLinearTransform(h);
  if (offset) transform->postTranslate(openvdb::Vec3d(offset->x(), offset->y(), 0));
  return transform;
}

}  // namespace

struct VdbWriter::Grids {
  explicit Grids(openvdb::math::Transform::Ptr t)
      : transform(std::move(t)), labels(openvdb::Int32Grid::create(0)), label_acc(labels->getAccessor()) {
    labels->setName(kVdbLabelGrid);
    labels->setTransform(transform);
    labels->setGridClass(openvdb::GRID_UNKNOWN);
    labels->insertMeta("description", openvdb::StringMetadata("unit label (unit id) per voxel, 0 = none"));
  }
  openvdb::math::Transform::Ptr transform;
  openvdb::Int32Grid::Ptr labels;
  openvdb::Int32Grid::Accessor label_acc;
  std::int32_t unit_label = 0;
  openvdb::FloatGrid::Ptr unit;  // the unit being filled
  std::optional<openvdb::FloatGrid::Accessor> unit_acc;
  openvdb::GridPtrVec done;
};

VdbWriter::VdbWriter(double voxel_size_m, const std::optional<Eigen::Vector2d>& offset)
    : grids_(std::make_unique<Grids>(voxel_transform(voxel_size_m, offset))), h_(voxel_size_m) {}

VdbWriter::~VdbWriter() = default;

Eigen::Vector3d VdbWriter::index_of(const Eigen::Vector3d& p) const {
  const openvdb::Vec3d idx = grids_->transform->worldToIndex(openvdb::Vec3d(p.x(), p.y(), p.z()));
  return {idx.x(), idx.y(), idx.z()};
}

void VdbWriter::begin_unit(const std::string& unit, std::int32_t label, const std::string& top_layer) {
  auto grid = openvdb::FloatGrid::create(0.0f);
  grid->setName(unit);
  grid->setTransform(grids_->transform);
  grid->setGridClass(openvdb::GRID_FOG_VOLUME);
  grid->insertMeta("unit", openvdb::StringMetadata(unit));
  grid->insertMeta("unit_label", openvdb::Int32Metadata(label));
  grid->insertMeta("top_layer", openvdb::StringMetadata(top_layer));
  grids_->unit = grid;
  grids_->unit_acc.emplace(grid->getAccessor());
  grids_->unit_label = label;
}

void VdbWriter::add_voxel(const std::array<int, 3>& ijk, double fraction, bool labelled) {
  if (std::abs(fraction - 1) < kPruneTolerance) fraction = 1;
  const openvdb::Coord c(ijk[0], ijk[1], ijk[2]);
  grids_->unit_acc->setValue(c, float(fraction));
  if (labelled) grids_->label_acc.setValue(c, grids_->unit_label);
}

VdbUnitGrid VdbWriter::end_unit() {
  auto& grid = grids_->unit;
  grids_->unit_acc.reset();
  openvdb::tools::prune(grid->tree(), kPruneTolerance);
  VdbUnitGrid out;
  double sum = 0;
  for (auto v = grid->cbeginValueOn(); v; ++v) {
    sum += double(*v) * double(v.getVoxelCount());
    out.active_voxels += v.getVoxelCount();
  }
  out.fog_volume_m3 = sum * h_ * h_ * h_;
  grids_->done.push_back(grid);
  grid.reset();
  return out;
}

std::map<std::int32_t, std::size_t> VdbWriter::write(
    const fs::path& path, const Eigen::Vector3d& site_origin, const std::string& crs,
    const std::vector<std::pair<std::int32_t, std::string>>& unit_labels) {
  // Labelled voxels per unit, after every unit has been written (a later unit
  // may take a voxel an earlier one claimed where solids overlap).
  std::map<std::int32_t, std::size_t> counts;
  for (auto v = grids_->labels->cbeginValueOn(); v; ++v) counts[*v] += v.getVoxelCount();
  openvdb::tools::prune(grids_->labels->tree());
  openvdb::GridPtrVec grids = grids_->done;
  grids.push_back(grids_->labels);

  openvdb::MetaMap meta;
  meta.insertMeta("site_origin_e", openvdb::DoubleMetadata(site_origin.x()));
  meta.insertMeta("site_origin_n", openvdb::DoubleMetadata(site_origin.y()));
  meta.insertMeta("site_origin_z", openvdb::DoubleMetadata(site_origin.z()));
  meta.insertMeta("crs", openvdb::StringMetadata(crs));
  meta.insertMeta("voxel_size_m", openvdb::DoubleMetadata(h_));
  meta.insertMeta("frame", openvdb::StringMetadata("site frame: CRS coordinates minus site_origin, metres"));
  for (const auto& [label, unit] : unit_labels)
    meta.insertMeta(fmt::format("label_{}", label), openvdb::StringMetadata(unit));

  write_atomically(path, "writer.vdb", [&](const fs::path& tmp) {
    try {
      openvdb::io::File file(tmp.string());
      file.write(grids, meta);
      file.close();
      make_vdb_uuid_from_content(tmp);
    } catch (const openvdb::Exception& e) {
      throw IoError(fmt::format("writer.vdb: {}: {}", path.string(), e.what()));
    }
  });
  return counts;
}

}  // namespace strata
