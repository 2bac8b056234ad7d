// TSDF fusion in OpenVDB and everything read from the fused level set: the only
// translation unit of the module that includes OpenVDB.
//
// Curless & Levoy 1996, "A Volumetric Method for Building Complex Models from Range
// Images": every depth map adds, to the voxels near its surface, the truncated signed
// distance along the view ray, averaged with per-observation weights; the surface is
// the zero level set. Only the narrow band (|d| < truncation) is allocated, in a
// sparse OpenVDB tree (Museth 2013), so a whole trench at millimetre voxels fits in
// memory. Sign convention of OpenVDB level sets: negative inside (below/behind the
// observed surface), positive outside (towards the cameras).
#include "core/disjoint_sets.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/vdb_uuid.hpp"
#include "dense/internal.hpp"

#include <fmt/format.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/LevelSetMeasure.h>
#include <openvdb/tools/Prune.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <openvdb/tree/LeafManager.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <optional>
#include <unordered_map>

namespace strata::dense {
namespace {

constexpr const char* kSurfaceGrid = "surface";
constexpr const char* kWeightGrid = "weight";
constexpr const char* kColourGrid = "colour";
// The agreement of the observations: per voxel, the weighted variance of the
// truncated distances averaged into it (m2) and the sum of the squared weights
// (their effective number is W^2 / sum w^2). They give each surface cell its
// height uncertainty (top_surface).
constexpr const char* kSpreadGrid = "spread";
constexpr const char* kWeight2Grid = "weight2";
// Prior of one observation's standard deviation, in voxels, and its strength in
// observations: a cell seen once has no agreement to measure and keeps this prior.
constexpr double kPriorSigmaVoxels = 1.0;
constexpr double kPriorObservations = 1.0;

void init_openvdb() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

openvdb::Vec3d to_vdb(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

}  // namespace

struct TsdfVolume::Impl {
  double voxel = 0;  // metres
  double trunc = 0;  // metres
  openvdb::FloatGrid::Ptr tsdf;    // truncated signed distance, metres; background +trunc
  openvdb::FloatGrid::Ptr weight;  // accumulated weight; background 0 (may be null when read)
  openvdb::Vec3SGrid::Ptr colour;  // RGB 0..255 weighted mean; background 0 (may be null)
  openvdb::FloatGrid::Ptr spread;  // weighted variance of the distances, m2 (may be null: older files)
  openvdb::FloatGrid::Ptr weight2; // sum of squared weights (null with spread)
  // The range scan being added (add_scan_points .. end_scan): per voxel, the sums of
  // the lateral weights g, of g times the signed distance (metres) and of g^2; with
  // colours, the sum of g times the colour (null when the scan has none).
  openvdb::Vec3SGrid::Ptr scan;
  openvdb::Vec3SGrid::Ptr scan_colour;
  std::optional<bool> scan_coloured;  // whether the scan's chunks have colours, once one came
  // While scans are fused: the voxels whose colour came from photos (taken when the
  // first scan starts; photos are fused first), and per voxel the weight of the scan
  // colours averaged into `colour` elsewhere.
  openvdb::MaskGrid::Ptr photo_coloured;
  openvdb::FloatGrid::Ptr scan_colour_weight;

  // The photo-coloured voxels: those photos gave weight before the first scan.
  void mark_photo_colours() {
    photo_coloured = openvdb::MaskGrid::create(false);
    photo_coloured->setTransform(tsdf->transform().copy());
    scan_colour_weight = openvdb::FloatGrid::create(0.f);
    scan_colour_weight->setTransform(tsdf->transform().copy());
    auto acc = photo_coloured->getAccessor();
    for (auto it = weight->cbeginValueOn(); it; ++it) {
      if (!(*it > 0)) continue;
      if (it.isVoxelValue())
        acc.setValueOn(it.getCoord());
      else
        photo_coloured->fill(it.getBoundingBox(), true, true);
    }
  }

  // True when the 2x2x2 voxels from `base` are all observed: a zero crossing there
  // is surface, not the edge of the narrow band next to unseen space.
  bool cell_observed(const openvdb::FloatGrid::ConstAccessor& acc, const openvdb::Coord& base) const {
    for (int dz = 0; dz < 2; ++dz)
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx)
          if (!acc.isValueOn(base.offsetBy(dx, dy, dz))) return false;
    return true;
  }
};

TsdfVolume::TsdfVolume(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

TsdfVolume::TsdfVolume(double voxel_size_m, double truncation_m) : impl_(std::make_unique<Impl>()) {
  STRATA_CHECK(voxel_size_m > 0 && truncation_m >= voxel_size_m, "bad voxel {} / truncation {}",
               voxel_size_m, truncation_m);
  init_openvdb();
  impl_->voxel = voxel_size_m;
  impl_->trunc = truncation_m;
  auto transform = openvdb::math::Transform::createLinearTransform(voxel_size_m);
  impl_->tsdf = openvdb::FloatGrid::create(static_cast<float>(truncation_m));
  impl_->tsdf->setTransform(transform);
  impl_->tsdf->setGridClass(openvdb::GRID_LEVEL_SET);
  impl_->tsdf->setName(kSurfaceGrid);
  impl_->weight = openvdb::FloatGrid::create(0.f);
  impl_->weight->setTransform(transform->copy());
  impl_->weight->setName(kWeightGrid);
  impl_->colour = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.f));
  impl_->colour->setTransform(transform->copy());
  impl_->colour->setName(kColourGrid);
  impl_->spread = openvdb::FloatGrid::create(0.f);
  impl_->spread->setTransform(transform->copy());
  impl_->spread->setName(kSpreadGrid);
  impl_->weight2 = openvdb::FloatGrid::create(0.f);
  impl_->weight2->setTransform(transform->copy());
  impl_->weight2->setName(kWeight2Grid);
}

TsdfVolume::~TsdfVolume() = default;

double TsdfVolume::voxel_size() const { return impl_->voxel; }
std::size_t TsdfVolume::active_voxels() const { return impl_->tsdf->activeVoxelCount(); }

void TsdfVolume::integrate(const PinholeCamera& cam, const DepthMap& depth,
                           const std::vector<std::uint8_t>& rgb) {
  STRATA_CHECK(depth.width == cam.width && depth.height == cam.height, "depth/camera size mismatch");
  STRATA_CHECK(impl_->weight && impl_->colour && impl_->spread && impl_->weight2,
               "volume read from a file cannot integrate");
  STRATA_CHECK(!impl_->photo_coloured, "depth maps are integrated before the scans");
  auto& I = *impl_;
  const auto& xform = I.tsdf->transform();

  // 1. The narrow band this depth map touches: voxels within +-trunc of each
  //    observed point along its view ray (sampled at half-voxel steps).
  openvdb::MaskGrid band(false);
  {
    auto acc = band.getAccessor();
    const double step = 0.5 * I.voxel;
    const int n_steps = static_cast<int>(std::ceil(2 * I.trunc / step));
    for (int v = 0; v < depth.height; ++v) {
      for (int u = 0; u < depth.width; ++u) {
        const float d = depth.depth[static_cast<std::size_t>(v) * depth.width + u];
        if (!(d > 0)) continue;
        const Eigen::Vector3d Xc = cam.ray_point(u, v, d);
        const Eigen::Vector3d dir = Xc.normalized();
        const Eigen::Vector3d start = Xc - dir * I.trunc;
        for (int s = 0; s <= n_steps; ++s) {
          const Eigen::Vector3d Xw = cam.to_world(start + dir * (s * step));
          acc.setValueOn(xform.worldToIndexNodeCentered(to_vdb(Xw)));
        }
      }
    }
  }
  I.tsdf->tree().topologyUnion(band.tree());
  I.weight->tree().topologyUnion(band.tree());
  I.colour->tree().topologyUnion(band.tree());
  I.spread->tree().topologyUnion(band.tree());
  I.weight2->tree().topologyUnion(band.tree());

  // 2. Projective update of every band voxel (parallel over leaves; the leaves of the
  //    three grids exist after the unions, so each task writes only its own leaf).
  openvdb::tree::LeafManager<openvdb::MaskTree> leaves(band.tree());
  const float trunc = static_cast<float>(I.trunc);
  leaves.foreach([&](const openvdb::MaskTree::LeafNodeType& leaf, std::size_t) {
    auto* tl = I.tsdf->tree().probeLeaf(leaf.origin());
    auto* wl = I.weight->tree().probeLeaf(leaf.origin());
    auto* cl = I.colour->tree().probeLeaf(leaf.origin());
    auto* sl = I.spread->tree().probeLeaf(leaf.origin());
    auto* ql = I.weight2->tree().probeLeaf(leaf.origin());
    if (!tl || !wl || !cl || !sl || !ql) return;
    for (auto it = leaf.cbeginValueOn(); it; ++it) {
      const openvdb::Vec3d w = xform.indexToWorld(it.getCoord());
      const Eigen::Vector3d Xc = cam.pose.to_camera(Eigen::Vector3d(w.x(), w.y(), w.z()));
      if (Xc.z() <= 0) continue;
      const int u = static_cast<int>(std::lround(cam.fx * Xc.x() / Xc.z() + cam.cx));
      const int v = static_cast<int>(std::lround(cam.fy * Xc.y() / Xc.z() + cam.cy));
      if (u < 0 || v < 0 || u >= cam.width || v >= cam.height) continue;
      const std::size_t p = static_cast<std::size_t>(v) * cam.width + u;
      const float d = depth.depth[p];
      if (!(d > 0)) continue;
      // Signed distance along the ray: (observed depth - voxel depth) scaled from z to
      // ray length; positive in front of the surface.
      const double ray_scale = Xc.norm() / Xc.z();
      float sdf = static_cast<float>((d - Xc.z()) * ray_scale);
      if (sdf < -trunc) continue;  // far behind the surface: occluded, no information
      sdf = std::min(sdf, trunc);
      // Weight: the pixel's confidence, lower for grazing views (Curless & Levoy
      // weight by the angle between the surface normal and the view ray).
      const Eigen::Vector3d n(depth.normal[3 * p], depth.normal[3 * p + 1], depth.normal[3 * p + 2]);
      const double cos_view = std::abs(n.dot(Xc.normalized()));
      const float obs_w = depth.confidence[p] * static_cast<float>(std::max(0.2, cos_view));
      if (!(obs_w > 0)) continue;
      const auto off = it.pos();
      const float W = wl->getValue(off);
      const float Wn = W + obs_w;
      // Weighted mean and variance in one pass (West 1979): the variance grows by
      // w * (x - old mean) * (x - new mean).
      const float mean = W > 0 ? tl->getValue(off) : sdf;
      const float mean_n = (mean * W + sdf * obs_w) / Wn;
      tl->setValueOnly(off, mean_n);
      wl->setValueOnly(off, Wn);
      sl->setValueOnly(off, (sl->getValue(off) * W + obs_w * (sdf - mean) * (sdf - mean_n)) / Wn);
      ql->setValueOnly(off, ql->getValue(off) + obs_w * obs_w);
      const openvdb::Vec3s c(rgb[3 * p], rgb[3 * p + 1], rgb[3 * p + 2]);
      cl->setValueOnly(off, (cl->getValue(off) * W + c * obs_w) / Wn);
    }
  });
}

void TsdfVolume::add_scan_points(const std::vector<Eigen::Vector3d>& points,
                                 const std::vector<Eigen::Vector3d>& dirs, const std::vector<double>& relative_weights,
                                 const std::vector<Rgb8>& colours) {
  STRATA_CHECK(points.size() == dirs.size(), "{} scan points but {} ray directions", points.size(), dirs.size());
  STRATA_CHECK(relative_weights.empty() || relative_weights.size() == points.size(), "{} scan points but {} weights",
               points.size(), relative_weights.size());
  STRATA_CHECK(colours.empty() || colours.size() == points.size(), "{} scan points but {} colours", points.size(),
               colours.size());
  STRATA_CHECK(impl_->weight && impl_->colour && impl_->spread && impl_->weight2,
               "volume read from a file cannot integrate");
  auto& I = *impl_;
  if (!I.photo_coloured) I.mark_photo_colours();
  if (!I.scan) {
    I.scan = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.f));
    I.scan->setTransform(I.tsdf->transform().copy());
  }
  const bool coloured = !colours.empty();
  if (points.empty()) return;
  STRATA_CHECK(!I.scan_coloured || *I.scan_coloured == coloured, "a scan's chunks with and without colours");
  I.scan_coloured = coloured;
  if (coloured && !I.scan_colour) {
    I.scan_colour = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.f));
    I.scan_colour->setTransform(I.tsdf->transform().copy());
  }
  const auto& xform = I.tsdf->transform();
  auto acc = I.scan->getAccessor();
  std::optional<openvdb::Vec3SGrid::Accessor> colour_acc;
  if (coloured) colour_acc.emplace(I.scan_colour->getAccessor());
  const double step = 0.5 * I.voxel;
  const int n_steps = static_cast<int>(std::ceil(2 * I.trunc / step));
  const double inv_v2 = 1.0 / (I.voxel * I.voxel);
  std::vector<openvdb::Coord> cells;
  cells.reserve(8 * static_cast<std::size_t>(n_steps + 1));
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d& p = points[i];
    const Eigen::Vector3d& u = dirs[i];
    const float pw = relative_weights.empty() ? 1.f : static_cast<float>(relative_weights[i]);
    // Every voxel of the 2 x 2 x 2 blocks around the samples, once per point.
    cells.clear();
    for (int s = 0; s <= n_steps; ++s) {
      const Eigen::Vector3d X = p - u * (I.trunc - s * step);
      const openvdb::Coord base = openvdb::Coord::floor(xform.worldToIndex(to_vdb(X)));
      for (int k = 0; k < 8; ++k) cells.push_back(base.offsetBy(k & 1, (k >> 1) & 1, (k >> 2) & 1));
    }
    std::sort(cells.begin(), cells.end());
    cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
    for (const openvdb::Coord& c : cells) {
      const openvdb::Vec3d w = xform.indexToWorld(c);
      const Eigen::Vector3d off = p - Eigen::Vector3d(w.x(), w.y(), w.z());
      // Signed distance of the voxel centre along the ray: positive in front of the
      // point (towards the sensor), as for depth maps.
      const double d = off.dot(u);
      if (std::abs(d) > I.trunc) continue;
      const double lateral2 = (off - d * u).squaredNorm();
      const float g = static_cast<float>(std::exp(-0.5 * lateral2 * inv_v2));
      const openvdb::Vec3s old = acc.getValue(c);
      acc.setValue(c, openvdb::Vec3s(old[0] + pw * g, old[1] + pw * g * static_cast<float>(d), old[2] + pw * g * g));
      if (colour_acc) {
        const Rgb8& rgb = colours[i];
        colour_acc->setValue(c, colour_acc->getValue(c) + openvdb::Vec3s(rgb[0], rgb[1], rgb[2]) * (pw * g));
      }
    }
  }
}

TsdfVolume::ScanFusion TsdfVolume::end_scan(double weight_per_point) {
  STRATA_CHECK(weight_per_point > 0 && std::isfinite(weight_per_point), "bad scan weight {}", weight_per_point);
  auto& I = *impl_;
  ScanFusion out;
  if (!I.scan) return out;
  I.tsdf->tree().topologyUnion(I.scan->tree());
  I.weight->tree().topologyUnion(I.scan->tree());
  I.colour->tree().topologyUnion(I.scan->tree());
  I.spread->tree().topologyUnion(I.scan->tree());
  I.weight2->tree().topologyUnion(I.scan->tree());
  auto tacc = I.tsdf->getAccessor();
  auto wacc = I.weight->getAccessor();
  auto cacc = I.colour->getAccessor();
  auto sacc = I.spread->getAccessor();
  auto qacc = I.weight2->getAccessor();
  auto photo = I.photo_coloured->getConstAccessor();
  auto scw = I.scan_colour_weight->getAccessor();
  std::optional<openvdb::Vec3SGrid::ConstAccessor> scan_colour;
  if (I.scan_colour) scan_colour.emplace(I.scan_colour->getConstAccessor());
  for (auto it = I.scan->cbeginValueOn(); it; ++it) {
    if (!it.isVoxelValue()) continue;
    const openvdb::Vec3s a = *it;
    if (!(a[0] > 0) || !(a[2] > 0)) continue;
    const openvdb::Coord c = it.getCoord();
    const float sdf = std::clamp(a[1] / a[0], -static_cast<float>(I.trunc), static_cast<float>(I.trunc));
    const double n_eff = double(a[0]) * a[0] / a[2];
    const float obs_w = static_cast<float>(weight_per_point * n_eff);
    // The same running weighted mean and variance as integrate() (West 1979).
    const float W = wacc.getValue(c);
    const float Wn = W + obs_w;
    const float mean = W > 0 ? tacc.getValue(c) : sdf;
    const float mean_n = (mean * W + sdf * obs_w) / Wn;
    tacc.setValueOnly(c, mean_n);
    wacc.setValueOnly(c, Wn);
    sacc.setValueOnly(c, (sacc.getValue(c) * W + obs_w * (sdf - mean) * (sdf - mean_n)) / Wn);
    qacc.setValueOnly(c, qacc.getValue(c) + obs_w * obs_w);
    // Colour: the photos' where they saw the voxel; else the weighted mean of the
    // coloured scans' observations; grey where neither saw it.
    if (!photo.isValueOn(c)) {
      const float cw = scw.getValue(c);
      if (scan_colour) {
        const openvdb::Vec3s rgb = scan_colour->getValue(c) / a[0];
        cacc.setValueOnly(c, cw > 0 ? (cacc.getValue(c) * cw + rgb * obs_w) / (cw + obs_w) : rgb);
        scw.setValue(c, cw + obs_w);
      } else if (!(cw > 0)) {
        cacc.setValueOnly(c, openvdb::Vec3s(128.f));
      }
    }
    ++out.voxels;
    out.weight += obs_w;
  }
  I.scan = nullptr;
  I.scan_colour = nullptr;
  I.scan_coloured.reset();
  return out;
}

double TsdfVolume::total_weight() const {
  double sum = 0;
  for (auto it = impl_->weight->cbeginValueOn(); it; ++it) sum += double(*it) * double(it.getVoxelCount());
  return sum;
}

void TsdfVolume::finalise(double min_weight) {
  auto& I = *impl_;
  if (!I.weight) return;
  const float wmin = static_cast<float>(std::max(min_weight, 1e-6));
  openvdb::tree::LeafManager<openvdb::FloatTree> leaves(I.weight->tree());
  leaves.foreach([&](openvdb::FloatTree::LeafNodeType& wl, std::size_t) {
    auto* tl = I.tsdf->tree().probeLeaf(wl.origin());
    auto* cl = I.colour->tree().probeLeaf(wl.origin());
    auto* sl = I.spread ? I.spread->tree().probeLeaf(wl.origin()) : nullptr;
    auto* ql = I.weight2 ? I.weight2->tree().probeLeaf(wl.origin()) : nullptr;
    for (auto it = wl.beginValueOn(); it; ++it) {
      if (*it >= wmin) continue;
      const auto off = it.pos();
      wl.setValueOff(off, 0.f);
      if (tl) tl->setValueOff(off, I.tsdf->background());
      if (cl) cl->setValueOff(off, openvdb::Vec3s(0.f));
      if (sl) sl->setValueOff(off, 0.f);
      if (ql) ql->setValueOff(off, 0.f);
    }
  });
  openvdb::tools::pruneInactive(I.tsdf->tree());
  openvdb::tools::pruneInactive(I.weight->tree());
  openvdb::tools::pruneInactive(I.colour->tree());
  if (I.spread) openvdb::tools::pruneInactive(I.spread->tree());
  if (I.weight2) openvdb::tools::pruneInactive(I.weight2->tree());
  I.photo_coloured = nullptr;  // the fusion is over: the scans' colour bookkeeping goes
  I.scan_colour_weight = nullptr;
}

std::size_t TsdfVolume::remove_small_components(double min_fraction) {
  auto& I = *impl_;
  if (!(min_fraction > 0)) return 0;
  // Union-find over the active voxels, numbered in tree order in an Int32 grid of
  // the same topology (a few bytes per voxel; OpenVDB's segmentation builds a tree
  // per piece, gigabytes for the tens of thousands of specks of a real band).
  openvdb::Int32Grid::Ptr ids = openvdb::Int32Grid::create(-1);
  ids->tree().topologyUnion(I.tsdf->tree());
  std::int32_t n = 0;
  for (auto it = ids->tree().beginValueOn(); it; ++it) {
    if (it.isVoxelValue()) it.setValue(n++);
  }
  if (n == 0) return 0;
  DisjointSets<std::int32_t> pieces(static_cast<std::size_t>(n));
  auto find = [&](std::int32_t x) { return pieces.find(x); };
  {
    auto acc = ids->getConstAccessor();
    for (auto it = ids->tree().cbeginValueOn(); it; ++it) {
      if (!it.isVoxelValue()) continue;
      const openvdb::Coord c = it.getCoord();
      for (const openvdb::Coord& d : {openvdb::Coord(1, 0, 0), openvdb::Coord(0, 1, 0), openvdb::Coord(0, 0, 1)}) {
        std::int32_t other = -1;
        if (!acc.probeValue(c + d, other) || other < 0) continue;
        pieces.unite(*it, other);
      }
    }
  }
  std::vector<std::int32_t> size(static_cast<std::size_t>(n), 0);
  for (std::int32_t k = 0; k < n; ++k) ++size[static_cast<std::size_t>(find(k))];
  const double min_voxels = min_fraction * double(n);
  std::size_t removed = 0;
  auto tsdf = I.tsdf->getAccessor();
  auto weight = I.weight ? std::optional(I.weight->getAccessor()) : std::nullopt;
  auto colour = I.colour ? std::optional(I.colour->getAccessor()) : std::nullopt;
  auto spread = I.spread ? std::optional(I.spread->getAccessor()) : std::nullopt;
  auto weight2 = I.weight2 ? std::optional(I.weight2->getAccessor()) : std::nullopt;
  for (auto it = ids->tree().cbeginValueOn(); it; ++it) {
    if (!it.isVoxelValue() || double(size[static_cast<std::size_t>(find(*it))]) >= min_voxels) continue;
    const openvdb::Coord c = it.getCoord();
    tsdf.setValueOff(c, I.tsdf->background());
    if (weight) weight->setValueOff(c, 0.f);
    if (colour) colour->setValueOff(c, openvdb::Vec3s(0.f));
    if (spread) spread->setValueOff(c, 0.f);
    if (weight2) weight2->setValueOff(c, 0.f);
    ++removed;
  }
  if (removed == 0) return 0;
  openvdb::tools::pruneInactive(I.tsdf->tree());
  if (I.weight) openvdb::tools::pruneInactive(I.weight->tree());
  if (I.colour) openvdb::tools::pruneInactive(I.colour->tree());
  if (I.spread) openvdb::tools::pruneInactive(I.spread->tree());
  if (I.weight2) openvdb::tools::pruneInactive(I.weight2->tree());
  return removed;
}

DenseMesh TsdfVolume::extract_mesh(double adaptivity) const {
  const auto& I = *impl_;
  std::vector<openvdb::Vec3s> points;
  std::vector<openvdb::Vec3I> triangles;
  std::vector<openvdb::Vec4I> quads;
  openvdb::tools::volumeToMesh(*I.tsdf, points, triangles, quads, 0.0, adaptivity);

  const auto& xform = I.tsdf->transform();
  auto acc = I.tsdf->getConstAccessor();
  auto keep = [&](std::initializer_list<unsigned> idx) {
    openvdb::Vec3d c(0.0);
    for (unsigned k : idx) c += openvdb::Vec3d(points[k]);
    c /= static_cast<double>(idx.size());
    const openvdb::Vec3d ijk = xform.worldToIndex(c);
    return I.cell_observed(acc, openvdb::Coord::floor(ijk));
  };
  DenseMesh mesh;
  std::vector<int> remap(points.size(), -1);
  auto vertex = [&](unsigned k) {
    if (remap[k] < 0) {
      remap[k] = static_cast<int>(mesh.vertices.size());
      mesh.vertices.emplace_back(points[k].x(), points[k].y(), points[k].z());
    }
    return remap[k];
  };
  // OpenVDB winds polygons clockwise seen from the positive (outside) side; reverse
  // them so that normals point out of the level set (up, towards the cameras).
  for (const auto& t : triangles) {
    if (!keep({t[0], t[1], t[2]})) continue;
    mesh.faces.push_back({vertex(t[2]), vertex(t[1]), vertex(t[0])});
  }
  for (const auto& q : quads) {
    if (!keep({q[0], q[1], q[2], q[3]})) continue;
    const int a = vertex(q[0]), b = vertex(q[1]), c = vertex(q[2]), d = vertex(q[3]);
    mesh.faces.push_back({c, b, a});
    mesh.faces.push_back({d, c, a});
  }
  colour_vertices(mesh);
  return mesh;
}

void TsdfVolume::colour_vertices(DenseMesh& mesh) const {
  const auto& I = *impl_;
  if (!I.colour) return;
  mesh.colours.resize(mesh.vertices.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, mesh.vertices.size()),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      auto cacc = I.colour->getConstAccessor();
                      auto wacc = I.weight->getConstAccessor();
                      const auto& xform = I.colour->transform();
                      for (std::size_t i = r.begin(); i < r.end(); ++i) {
                        // Weight-normalised trilinear colour: unseen voxels (colour 0)
                        // must not darken vertices at the edge of the band.
                        const openvdb::Vec3d ijk = xform.worldToIndex(to_vdb(mesh.vertices[i]));
                        const openvdb::Coord base = openvdb::Coord::floor(ijk);
                        const openvdb::Vec3d f = ijk - base.asVec3d();
                        openvdb::Vec3d sum(0.0);
                        double wsum = 0;
                        for (int k = 0; k < 8; ++k) {
                          const openvdb::Coord c = base.offsetBy(k & 1, (k >> 1) & 1, (k >> 2) & 1);
                          if (!wacc.isValueOn(c)) continue;
                          const double w = ((k & 1) ? f.x() : 1 - f.x()) *
                                           (((k >> 1) & 1) ? f.y() : 1 - f.y()) *
                                           (((k >> 2) & 1) ? f.z() : 1 - f.z()) + 1e-6;
                          sum += openvdb::Vec3d(cacc.getValue(c)) * w;
                          wsum += w;
                        }
                        const openvdb::Vec3d rgb = wsum > 0 ? sum / wsum : openvdb::Vec3d(128.0);
                        for (int k = 0; k < 3; ++k) {
                          mesh.colours[i][k] =
                              static_cast<std::uint8_t>(std::clamp(std::lround(rgb[k]), 0L, 255L));
                        }
                      }
                    });
}

DenseMesh TsdfVolume::points_from_mesh(const DenseMesh& full_mesh, double min_weight, double min_observations) const {
  // The vertices of the unsimplified zero-level-set mesh: one point per surface
  // cell, already on the surface, with the level-set gradient as normal; those whose
  // nearest voxel was seen too little are left out.
  const auto& I = *impl_;
  std::vector<char> keep(full_mesh.vertices.size(), 1);
  if ((min_weight > 0 || min_observations > 0) && I.weight) {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, full_mesh.vertices.size()),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        auto wacc = I.weight->getConstAccessor();
                        std::optional<openvdb::FloatGrid::ConstAccessor> qacc;
                        if (I.weight2) qacc.emplace(I.weight2->getConstAccessor());
                        const auto& xform = I.weight->transform();
                        for (std::size_t i = r.begin(); i < r.end(); ++i) {
                          const openvdb::Coord c = xform.worldToIndexCellCentered(to_vdb(full_mesh.vertices[i]));
                          const double w = wacc.getValue(c);
                          const double w2 = qacc ? double(qacc->getValue(c)) : 0.0;
                          const double n_eff = w2 > 0 ? w * w / w2 : 0.0;
                          keep[i] = (w >= min_weight || (qacc && n_eff >= min_observations)) ? 1 : 0;
                        }
                      });
  }
  DenseMesh mesh;
  for (std::size_t i = 0; i < full_mesh.vertices.size(); ++i) {
    if (!keep[i]) continue;
    mesh.vertices.push_back(full_mesh.vertices[i]);
    if (i < full_mesh.colours.size()) mesh.colours.push_back(full_mesh.colours[i]);
  }
  mesh.normals.resize(mesh.vertices.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, mesh.vertices.size()),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      auto acc = I.tsdf->getConstAccessor();
                      openvdb::tools::GridSampler<openvdb::FloatGrid::ConstAccessor,
                                                  openvdb::tools::BoxSampler>
                          sampler(acc, I.tsdf->transform());
                      const double h = 0.5 * I.voxel;
                      for (std::size_t i = r.begin(); i < r.end(); ++i) {
                        const openvdb::Vec3d p = to_vdb(mesh.vertices[i]);
                        Eigen::Vector3d g;
                        for (int k = 0; k < 3; ++k) {
                          openvdb::Vec3d a = p, b = p;
                          a[k] += h;
                          b[k] -= h;
                          g[k] = sampler.wsSample(a) - sampler.wsSample(b);
                        }
                        const double n = g.norm();
                        mesh.normals[i] = n > 0 ? Eigen::Vector3f((g / n).cast<float>()) : Eigen::Vector3f::UnitZ();
                      }
                    });
  return mesh;
}

HeightRaster<double> TsdfVolume::top_surface(const RasterGrid& grid) const {
  STRATA_CHECK(grid.cell > 0 && grid.width >= 0 && grid.height >= 0, "bad height grid");
  const auto& I = *impl_;
  HeightRaster<double> hf = HeightRaster<double>::empty(grid);
  const openvdb::CoordBBox bbox = I.tsdf->evalActiveVoxelBoundingBox();
  if (bbox.empty()) return hf;

  // One pass over the active voxels: per voxel column (i, j), the highest crossing
  // from inside (<= 0) at k to outside (> 0) at k+1, both observed, linearly
  // interpolated. Index-space z, stored densely over the active XY box; with it
  // the height uncertainty of that crossing (metres, one sigma).
  const int ci0 = bbox.min().x(), cj0 = bbox.min().y();
  const int cw = bbox.dim().x(), ch = bbox.dim().y();
  const bool with_sigma = I.spread && I.weight && I.weight2;
  std::vector<float> column(static_cast<std::size_t>(cw) * ch, -std::numeric_limits<float>::infinity());
  std::vector<float> column_sigma(with_sigma ? column.size() : 0, 0.f);
  {
    auto acc = I.tsdf->getConstAccessor();
    std::optional<openvdb::FloatGrid::ConstAccessor> sacc, wacc, qacc;
    if (with_sigma) {
      sacc.emplace(I.spread->getConstAccessor());
      wacc.emplace(I.weight->getConstAccessor());
      qacc.emplace(I.weight2->getConstAccessor());
    }
    const double prior2 = std::pow(kPriorSigmaVoxels * I.voxel, 2);
    for (auto it = I.tsdf->cbeginValueOn(); it; ++it) {
      if (!it.isVoxelValue()) continue;
      const float a = *it;
      if (a > 0) continue;
      const openvdb::Coord c = it.getCoord();
      const openvdb::Coord up = c.offsetBy(0, 0, 1);
      float b = 0;
      if (!acc.probeValue(up, b) || !(b > 0)) continue;
      const float f = a / (a - b);
      const float z = static_cast<float>(c.z()) + f;
      const std::size_t k = static_cast<std::size_t>(c.y() - cj0) * cw + (c.x() - ci0);
      if (z <= column[k]) continue;
      column[k] = z;
      if (!with_sigma) continue;
      // The surface height's uncertainty from the observations' agreement: their
      // weighted spread, shrunk towards a prior (one observation has no spread to
      // measure), over their effective number W^2 / sum w^2.
      auto lerp = [&](const openvdb::FloatGrid::ConstAccessor& g) {
        return (1 - f) * g.getValue(c) + f * g.getValue(up);
      };
      const double var = std::max(0.f, lerp(*sacc)), W = lerp(*wacc), W2 = lerp(*qacc);
      const double n_eff = W2 > 0 ? std::max(1.0, W * W / W2) : 1.0;
      const double s2 = (kPriorObservations * prior2 + n_eff * var) / (kPriorObservations + n_eff);
      column_sigma[k] = static_cast<float>(std::sqrt(s2 / n_eff));
    }
  }
  auto col_index = [&](int i, int j) -> std::ptrdiff_t {
    if (i < ci0 || j < cj0 || i >= ci0 + cw || j >= cj0 + ch) return -1;
    return static_cast<std::ptrdiff_t>(j - cj0) * cw + (i - ci0);
  };
  auto col_at = [&](int i, int j) -> float {
    const auto k = col_index(i, j);
    return k < 0 ? -std::numeric_limits<float>::infinity() : column[static_cast<std::size_t>(k)];
  };
  auto sigma_at = [&](int i, int j) -> double {  // called only where col_at is finite, so inside the box
    const auto k = col_index(i, j);
    return k < 0 ? std::numeric_limits<double>::quiet_NaN() : column_sigma[static_cast<std::size_t>(k)];
  };
  if (with_sigma) hf.sigma.assign(hf.z.size(), std::numeric_limits<double>::quiet_NaN());
  // Bilinear over the four surrounding columns when all have a crossing, else the
  // nearest column's (edges of the surface, vertical walls).
  const double vs = I.voxel;
  for (int row = 0; row < grid.height; ++row) {
    for (int col = 0; col < grid.width; ++col) {
      const double fx = grid.x_centre(col) / vs, fy = grid.y_centre(row) / vs;
      const int i0 = static_cast<int>(std::floor(fx)), j0 = static_cast<int>(std::floor(fy));
      const double ax = fx - i0, ay = fy - j0;
      const float z00 = col_at(i0, j0), z10 = col_at(i0 + 1, j0), z01 = col_at(i0, j0 + 1),
                  z11 = col_at(i0 + 1, j0 + 1);
      double z = std::numeric_limits<double>::quiet_NaN(), sigma = z;
      if (std::isfinite(z00) && std::isfinite(z10) && std::isfinite(z01) && std::isfinite(z11)) {
        z = (1 - ay) * ((1 - ax) * z00 + ax * z10) + ay * ((1 - ax) * z01 + ax * z11);
        if (with_sigma)
          sigma = (1 - ay) * ((1 - ax) * sigma_at(i0, j0) + ax * sigma_at(i0 + 1, j0)) +
                  ay * ((1 - ax) * sigma_at(i0, j0 + 1) + ax * sigma_at(i0 + 1, j0 + 1));
      } else {
        const int in = static_cast<int>(std::lround(fx)), jn = static_cast<int>(std::lround(fy));
        const float zn = col_at(in, jn);
        if (std::isfinite(zn)) {
          z = zn;
          if (with_sigma) sigma = sigma_at(in, jn);
        }
      }
      if (std::isfinite(z)) {
        const std::size_t cidx = grid.index(col, row);
        hf.z[cidx] = z * vs;
        if (with_sigma) hf.sigma[cidx] = sigma;
      }
    }
  }
  return hf;
}

std::vector<double> TsdfVolume::distances(const std::vector<Eigen::Vector3d>& points) const {
  const auto& I = *impl_;
  std::vector<double> out(points.size(), std::numeric_limits<double>::quiet_NaN());
  auto acc = I.tsdf->getConstAccessor();
  openvdb::tools::GridSampler<openvdb::FloatGrid::ConstAccessor, openvdb::tools::BoxSampler> sampler(
      acc, I.tsdf->transform());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const openvdb::Vec3d p = to_vdb(points[i]);
    const openvdb::Coord base = openvdb::Coord::floor(I.tsdf->transform().worldToIndex(p));
    if (!I.cell_observed(acc, base)) continue;
    out[i] = std::abs(sampler.wsSample(p));
  }
  return out;
}

void TsdfVolume::signed_column(double x, double y, double z0, double dz, int n, double* out) const {
  const auto& I = *impl_;
  auto acc = I.tsdf->getConstAccessor();
  openvdb::tools::GridSampler<openvdb::FloatGrid::ConstAccessor, openvdb::tools::BoxSampler> sampler(
      acc, I.tsdf->transform());
  for (int k = 0; k < n; ++k) {
    const openvdb::Vec3d p(x, y, z0 + k * dz);
    const openvdb::Coord base = openvdb::Coord::floor(I.tsdf->transform().worldToIndex(p));
    out[k] = I.cell_observed(acc, base) ? sampler.wsSample(p) : std::numeric_limits<double>::quiet_NaN();
  }
}

double TsdfVolume::truncation() const { return impl_->trunc; }

double TsdfVolume::level_set_volume() const {
  return openvdb::tools::levelSetVolume(*impl_->tsdf, true);
}

void TsdfVolume::write(const std::filesystem::path& vdb, const Eigen::Vector3d& origin,
                       const std::string& crs) const {
  const auto& I = *impl_;
  openvdb::GridPtrVec grids;
  auto surface = I.tsdf->deepCopy();
  // The site origin travels with the grid, so a level set read on its own can still
  // be placed in the site CRS (design.md "Frames and precision").
  surface->insertMeta("site_origin_e", openvdb::DoubleMetadata(origin.x()));
  surface->insertMeta("site_origin_n", openvdb::DoubleMetadata(origin.y()));
  surface->insertMeta("site_origin_z", openvdb::DoubleMetadata(origin.z()));
  surface->insertMeta("crs", openvdb::StringMetadata(crs));
  surface->insertMeta("frame", openvdb::StringMetadata("site frame: site CRS minus site origin, metres"));
  surface->insertMeta("truncation_m", openvdb::DoubleMetadata(I.trunc));
  grids.push_back(surface);
  if (I.weight) grids.push_back(I.weight);
  if (I.colour) grids.push_back(I.colour);
  if (I.spread && I.weight2) {
    grids.push_back(I.spread);
    grids.push_back(I.weight2);
  }
  write_atomically(vdb, "writer.vdb", [&](const std::filesystem::path& tmp) {
    try {
      openvdb::io::File file(tmp.string());
      file.write(grids);
      file.close();
      make_vdb_uuid_from_content(tmp);
    } catch (const openvdb::Exception& e) {
      throw IoError(fmt::format("writer.vdb: {}: {}", tmp.string(), e.what()));
    }
  }, "process.dense.product_temp_written");
}

std::unique_ptr<TsdfVolume> TsdfVolume::read(const std::filesystem::path& vdb, LevelSetInfo* info) {
  init_openvdb();
  auto impl = std::make_unique<Impl>();
  try {
    openvdb::io::File file(vdb.string());
    file.open();
    if (!file.hasGrid(kSurfaceGrid)) {
      throw IoError(fmt::format("reader.vdb: {}: no grid named \"{}\"", vdb.string(), kSurfaceGrid));
    }
    impl->tsdf = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid(kSurfaceGrid));
    if (!impl->tsdf) {
      throw IoError(fmt::format("reader.vdb: {}: grid \"surface\" is not a float grid", vdb.string()));
    }
    if (file.hasGrid(kWeightGrid)) {
      impl->weight = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid(kWeightGrid));
    }
    if (file.hasGrid(kColourGrid)) {
      impl->colour = openvdb::gridPtrCast<openvdb::Vec3SGrid>(file.readGrid(kColourGrid));
    }
    if (file.hasGrid(kSpreadGrid) && file.hasGrid(kWeight2Grid) && impl->weight) {
      impl->spread = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid(kSpreadGrid));
      impl->weight2 = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid(kWeight2Grid));
      if (!impl->spread || !impl->weight2) impl->spread = impl->weight2 = nullptr;
    }
    file.close();
  } catch (const openvdb::Exception& e) {
    throw IoError(fmt::format("reader.vdb: {}: {}", vdb.string(), e.what()));
  }
  if (!impl->weight || !impl->colour) {
    impl->weight = nullptr;
    impl->colour = nullptr;
    impl->spread = impl->weight2 = nullptr;
  }
  impl->voxel = impl->tsdf->voxelSize().x();
  impl->trunc = impl->tsdf->background();
  if (info) {
    info->voxel_size_m = impl->voxel;
    auto meta_d = [&](const char* key) {
      auto m = impl->tsdf->getMetadata<openvdb::DoubleMetadata>(key);
      return m ? m->value() : 0.0;
    };
    info->site_origin = {meta_d("site_origin_e"), meta_d("site_origin_n"), meta_d("site_origin_z")};
    auto crs = impl->tsdf->getMetadata<openvdb::StringMetadata>("crs");
    info->crs = crs ? crs->value() : std::string();
    const openvdb::CoordBBox bb = impl->tsdf->evalActiveVoxelBoundingBox();
    if (!bb.empty()) {
      const openvdb::Vec3d lo = impl->tsdf->indexToWorld(bb.min()), hi = impl->tsdf->indexToWorld(bb.max());
      info->min = {lo.x(), lo.y(), lo.z()};
      info->max = {hi.x(), hi.y(), hi.z()};
    }
  }
  return std::unique_ptr<TsdfVolume>(new TsdfVolume(std::move(impl)));
}

}  // namespace strata::dense

namespace strata {

LevelSetInfo read_level_set_info(const std::filesystem::path& vdb) {
  LevelSetInfo info;
  dense::TsdfVolume::read(vdb, &info);
  return info;
}

HeightRaster<double> sample_top_surface(const std::filesystem::path& vdb, const RasterGrid& grid) {
  if (!(grid.cell > 0) || grid.width < 0 || grid.height < 0) {
    throw InputError(
        fmt::format("sample_top_surface: bad grid (cell {} m, {} x {})", grid.cell, grid.width, grid.height));
  }
  return dense::TsdfVolume::read(vdb, nullptr)->top_surface(grid);
}

LevelSetProbe::LevelSetProbe(const std::filesystem::path& vdb) : volume_(dense::TsdfVolume::read(vdb, nullptr)) {}
LevelSetProbe::~LevelSetProbe() = default;
LevelSetProbe::LevelSetProbe(LevelSetProbe&&) noexcept = default;
double LevelSetProbe::voxel_size_m() const { return volume_->voxel_size(); }
double LevelSetProbe::truncation_m() const { return volume_->truncation(); }
void LevelSetProbe::column(double x, double y, double z0, double dz, int n, double* out) const {
  volume_->signed_column(x, y, z0, dz, n, out);
}

double level_set_volume_m3(const std::filesystem::path& vdb) {
  return dense::TsdfVolume::read(vdb, nullptr)->level_set_volume();
}

DenseMesh level_set_mesh(const std::filesystem::path& vdb, double adaptivity) {
  return dense::TsdfVolume::read(vdb, nullptr)->extract_mesh(adaptivity);
}

}  // namespace strata
