// The voxel model: per-unit fog volumes and the label grid, voxelized here and
// written by exporters/voxels (writer.vdb); its readers. The only translation unit of
// strata_volume that includes OpenVDB.
#include "volume/voxels.hpp"

#include "core/error.hpp"
#include "exporters/voxels/vdb_writer.hpp"

#include <fmt/format.h>
#include <openvdb/openvdb.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>

namespace strata {
namespace fs = std::filesystem;
namespace {

void init_vdb() {
  static const bool done = [] {
    openvdb::initialize();
    return true;
  }();
  (void)done;
}

// The offsets of the voxel grid from the site frame's origin put voxel faces on cell
// faces of the measurement grid, so that no cell centre lies on a voxel face (where
// rounding would pick a column at random). None without solids.
std::optional<Eigen::Vector2d> voxel_offset(const std::vector<UnitSolid>& solids, double h) {
  if (solids.empty()) return std::nullopt;
  const RasterGrid& g = solids.front().top.grid;
  return Eigen::Vector2d(std::fmod(g.x_min + 0.5 * h, h), std::fmod(g.y_min() + 0.5 * h, h));
}

// A dug cell of the measurement grid in the voxel column its centre falls in.
struct CellColumn {
  int I, J;
  double t, b;  // top and bottom, site frame, metres
};

// The solid's dug cells, by voxel column (J, then I). J grows northwards: the rows
// are read from the southern one up, so that the cells of a column (summed in
// voxelize_solid) come in the same order whatever the sort does with equal keys.
std::vector<CellColumn> dug_cells(const UnitSolid& solid, const VdbWriter& vdb) {
  const RasterGrid& g = solid.top.grid;
  std::vector<CellColumn> cells;
  for (int row = g.height - 1; row >= 0; --row)
    for (int col = 0; col < g.width; ++col) {
      const double t = solid.top.at(col, row), b = solid.bottom.at(col, row);
      if (!std::isfinite(t) || !(t > b)) continue;  // a negative thickness (footprint mode) adds no voxels
      const Eigen::Vector3d idx = vdb.index_of(Eigen::Vector3d(g.x_centre(col), g.y_centre(row), 0));
      cells.push_back({int(std::floor(idx.x() + 0.5)), int(std::floor(idx.y() + 0.5)), t, b});
    }
  std::sort(cells.begin(), cells.end(), [](const auto& p, const auto& q) { return p.J != q.J ? p.J < q.J : p.I < q.I; });
  return cells;
}

// Every dug cell goes to the voxel column its centre falls in; a voxel's fraction is
// the solid's volume inside it (sum over the column's cells of overlap x cell area)
// over the voxel's volume, so the fog conserves the raster volume exactly whatever
// the ratio of voxel to cell. A voxel more than half inside is labelled.
void voxelize_solid(const UnitSolid& solid, double h, VdbWriter& vdb) {
  const std::vector<CellColumn> cells = dug_cells(solid, vdb);
  const double cell_area_over_voxel = solid.top.grid.cell * solid.top.grid.cell / (h * h * h);
  for (std::size_t c0 = 0; c0 < cells.size();) {
    std::size_t c1 = c0;
    double zmin = 1e300, zmax = -1e300;
    while (c1 < cells.size() && cells[c1].I == cells[c0].I && cells[c1].J == cells[c0].J) {
      zmin = std::min(zmin, cells[c1].b);
      zmax = std::max(zmax, cells[c1].t);
      ++c1;
    }
    const int I = cells[c0].I, J = cells[c0].J;
    const int K0 = int(std::floor(zmin / h + 0.5)), K1 = int(std::floor(zmax / h + 0.5));
    for (int K = K0; K <= K1; ++K) {
      const double lo = (K - 0.5) * h, hi = (K + 0.5) * h;
      double overlap = 0;  // metres, summed over the column's cells
      for (std::size_t c = c0; c < c1; ++c) overlap += std::max(0.0, std::min(cells[c].t, hi) - std::max(cells[c].b, lo));
      const double fraction = overlap * cell_area_over_voxel;
      if (fraction <= 0) continue;
      vdb.add_voxel({I, J, K}, fraction, fraction > 0.5);
    }
    c0 = c1;
  }
}

}  // namespace

void VoxelOptions::validate() const {
  if (!(voxel_size_m >= 0.001 && voxel_size_m <= 1.0))
    throw InputError(fmt::format("voxel options: voxel_size_m = {} is not in 0.001..1 m", voxel_size_m));
}

VoxelSummary write_unit_voxels(const fs::path& path, const std::vector<UnitSolid>& solids,
                               const std::map<std::string, std::int32_t>& labels, const VoxelOptions& options,
                               const Eigen::Vector3d& site_origin, const std::string& crs) {
  options.validate();
  const double h = options.voxel_size_m;
  VdbWriter vdb(h, voxel_offset(solids, h));
  VoxelSummary summary;
  summary.voxel_size_m = h;
  std::vector<std::pair<std::int32_t, std::string>> unit_labels;
  std::int32_t next_label = 1;
  for (const auto& solid : solids) {
    VoxelUnit vu;
    vu.unit = solid.unit;
    const auto it = labels.find(solid.unit);
    vu.label = it != labels.end() ? it->second : next_label++;
    vdb.begin_unit(solid.unit, vu.label, solid.top_layer);
    voxelize_solid(solid, h, vdb);
    const VdbUnitGrid grid = vdb.end_unit();
    vu.fog_volume_m3 = grid.fog_volume_m3;
    vu.active_voxels = grid.active_voxels;
    summary.units.push_back(vu);
    unit_labels.emplace_back(vu.label, vu.unit);
  }
  const std::map<std::int32_t, std::size_t> counts = vdb.write(path, site_origin, crs, unit_labels);
  for (auto& vu : summary.units) {
    const auto c = counts.find(vu.label);
    vu.labelled_voxels = c != counts.end() ? c->second : 0;
    vu.label_volume_m3 = double(vu.labelled_voxels) * h * h * h;
  }
  return summary;
}

namespace {

struct OpenedVdb {
  openvdb::GridPtrVecPtr grids;
  openvdb::MetaMap::Ptr meta;
};

OpenedVdb open_vdb(const fs::path& path) {
  init_vdb();
  if (!fs::exists(path)) throw IoError(fmt::format("reader.vdb: {}: no such file", path.string()));
  try {
    openvdb::io::File file(path.string());
    file.open();
    OpenedVdb out{file.getGrids(), file.getMetadata()};
    file.close();
    return out;
  } catch (const openvdb::Exception& e) {
    throw IoError(fmt::format("reader.vdb: {}: {}", path.string(), e.what()));
  }
}

}  // namespace

std::map<std::string, double> read_voxel_volumes(const fs::path& path) {
  const OpenedVdb f = open_vdb(path);
  std::map<std::string, double> out;
  for (const auto& base : *f.grids) {
    auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(base);
    if (!grid || grid->getGridClass() != openvdb::GRID_FOG_VOLUME) continue;
    const openvdb::Vec3d v = grid->voxelSize();
    double sum = 0;
    for (auto it = grid->cbeginValueOn(); it; ++it) sum += double(*it) * double(it.getVoxelCount());
    out[grid->getName()] = sum * v.x() * v.y() * v.z();
  }
  return out;
}

LabelVolume read_label_volume(const fs::path& path) {
  const OpenedVdb f = open_vdb(path);
  openvdb::Int32Grid::Ptr grid;
  for (const auto& base : *f.grids)
    if (base->getName() == kVdbLabelGrid) grid = openvdb::gridPtrCast<openvdb::Int32Grid>(base);
  if (!grid) throw IoError(fmt::format("reader.vdb: {}: no Int32 grid named '{}'", path.string(), kVdbLabelGrid));
  LabelVolume out;
  out.voxel_size_m = grid->voxelSize().x();
  auto get_double = [&](const char* key) {
    auto m = f.meta->getMetadata<openvdb::DoubleMetadata>(key);
    return m ? m->value() : 0.0;
  };
  out.site_origin = {get_double("site_origin_e"), get_double("site_origin_n"), get_double("site_origin_z")};
  if (auto m = f.meta->getMetadata<openvdb::StringMetadata>("crs")) out.crs = m->value();
  for (auto it = f.meta->beginMeta(); it != f.meta->endMeta(); ++it) {
    if (it->first.rfind("label_", 0) != 0) continue;
    if (auto s = f.meta->getMetadata<openvdb::StringMetadata>(it->first))
      out.units[std::int32_t(std::stol(it->first.substr(6)))] = s->value();
  }
  const openvdb::CoordBBox box = grid->evalActiveVoxelBoundingBox();
  if (box.empty()) return out;
  const openvdb::Coord lo = box.min(), dim = box.dim();
  out.nx = dim.x();
  out.ny = dim.y();
  out.nz = dim.z();
  const openvdb::Vec3d c = grid->transform().indexToWorld(lo);
  out.min_centre = Eigen::Vector3d(c.x(), c.y(), c.z());
  out.labels.assign(std::size_t(out.nx) * out.ny * out.nz, 0);
  for (auto it = grid->cbeginValueOn(); it; ++it) {
    const openvdb::CoordBBox b = it.getBoundingBox();  // a voxel or a tile
    for (auto c = b.begin(); c; ++c) {
      const openvdb::Coord q = *c - lo;
      out.labels[(std::size_t(q.z()) * out.ny + q.y()) * out.nx + q.x()] = *it;
    }
  }
  return out;
}

}  // namespace strata
