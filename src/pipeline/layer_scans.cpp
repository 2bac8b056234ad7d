#include "pipeline/layer_scans.hpp"

#include "core/error.hpp"
#include "core/hash.hpp"
#include "crs/crs.hpp"
#include "pipeline/depth_frames.hpp"
#include "pipeline/scan_points.hpp"

#include <fmt/format.h>

#include <Eigen/Dense>

#include <memory>

namespace fs = std::filesystem;

namespace strata {
namespace {

// The reader of a scan in its scanner's frame, mapped by a similarity into the site frame.
RangeScanInput transformed_scan(const fs::path& file, const ScanRecord& s) {
  const Eigen::Matrix4d M = *s.transform;
  const Eigen::Matrix3d A = M.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = M.topRightCorner<3, 1>();
  ScanFrameMap map;
  map.point = [A, t](const Eigen::Vector3d& p) -> Eigen::Vector3d { return A * p + t; };
  map.normal = A.inverse().transpose().cast<float>();  // normals under a similarity
  RangeScanInput in;
  in.name = s.name;
  in.sigma_m = s.sigma_m;
  in.station = t;  // the scanner's origin, where every ray starts
  in.read = [file, map](const RangeScanInput::ChunkSink& sink) { read_scan_points(file, map, sink); };
  return in;
}

// The reader of a scan in a CRS (registered by the scanner's software): into the
// site CRS with PROJ (identity when they are the same), minus the site origin.
RangeScanInput survey_scan(const fs::path& file, const ScanRecord& s, const SiteInfo& site) {
  auto to_site = std::make_shared<CrsTransform>(
      transform_into_site(*s.crs, site.crs, fmt::format("dense.scans: {}: CRS", s.name)));
  const Eigen::Vector3d origin = site.origin;
  ScanFrameMap map;
  map.point = [to_site, origin](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return (to_site->identity() ? p : to_site->apply(p)) - origin;
  };
  RangeScanInput in;
  in.name = s.name;
  in.sigma_m = s.sigma_m;
  in.read = [file, map](const RangeScanInput::ChunkSink& sink) { read_scan_points(file, map, sink); };
  return in;
}

// Every other pixel each way: the frames of one loop overlap 10-20 times, and
// neighbouring pixels (3-5 mm apart at 1.5-2.5 m) are finer than the voxel; a quarter
// of the points keeps a sequence's fusion near a minute on two cores.
constexpr int kDepthFusionStride = 2;

void add_bounds(LayerScans& out, const ScanBounds& b) {
  if (!out.bounds) {
    out.bounds = b;
  } else {
    out.bounds->min = out.bounds->min.cwiseMin(b.min);
    out.bounds->max = out.bounds->max.cwiseMax(b.max);
  }
}

// The layer's registered depth frames; the sequences with frames still unregistered
// are named.
void add_depth_frames(Project& project, const LayerRecord& layer, LayerScans& out, CacheKey& key) {
  for (const DepthSequenceRecord& seq : list_depth_sequences(project.db(), layer.id)) {
    bool unregistered = false;
    for (const DepthFrameRecord& f : list_depth_frames(project.db(), seq.id)) {
      if (!f.pose) {
        unregistered = true;
        continue;
      }
      std::optional<fs::path> colour;
      if (f.colour_media_path) colour = project.dir() / *f.colour_media_path;
      out.registered.push_back(depth_frame_input(project.dir() / f.media_path, seq, f, kDepthFusionStride, colour));
      ++out.depth_frames;
      key.add(f.sha256).add(seq.noise_k).add(seq.depth_scale_m).add(*f.pose).add(kDepthFusionStride);
      key.add(f.colour_sha256.value_or(std::string()));
      if (f.bounds) add_bounds(out, *f.bounds);
    }
    if (unregistered) out.unregistered_depth.push_back(seq.name);
  }
}

}  // namespace

LayerScans layer_scans(Project& project, const LayerRecord& layer) {
  LayerScans out;
  const SiteInfo site = project.site();
  CacheKey key("registered scans v2");  // v2: colour frames fused
  for (const ScanRecord& s : list_scans(project.db(), layer.id)) {
    if (s.registration == ScanRegistration::unregistered) {
      out.unregistered.push_back(s.name);
      continue;
    }
    const fs::path file = project.dir() / s.media_path;
    if (s.registration == ScanRegistration::transform) {
      if (!s.transform) throw IoError(fmt::format("scans: {}: registered by a transform that is not stored", s.name));
      out.registered.push_back(transformed_scan(file, s));
    } else {
      if (!s.crs) throw IoError(fmt::format("scans: {}: registered to the survey without a CRS", s.name));
      out.registered.push_back(survey_scan(file, s, site));
    }
    key.add(s.sha256).add(s.sigma_m).add(s.registration).add(s.crs).add(s.transform);
    if (s.bounds) add_bounds(out, *s.bounds);
  }
  add_depth_frames(project, layer, out, key);
  if (!out.registered.empty()) out.key = key.hex();
  return out;
}

}  // namespace strata
