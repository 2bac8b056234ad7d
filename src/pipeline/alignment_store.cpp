#include "pipeline/alignment_store.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"
#include "pipeline/stage_json.hpp"
#include "project/gpkg.hpp"

#include <cstring>
#include <map>

namespace strata {
namespace {

template <typename T>
void put(std::vector<std::uint8_t>& out, T v) {
  const auto* p = reinterpret_cast<const std::uint8_t*>(&v);
  out.insert(out.end(), p, p + sizeof(T));
}
template <typename T>
T get(const std::vector<std::uint8_t>& in, std::size_t& at) {
  T v;
  std::memcpy(&v, in.data() + at, sizeof(T));
  at += sizeof(T);
  return v;
}
// Per point: 3 float64 + 3 uint8 + float32 + uint16 track length, then per track
// element uint32 image index (in the layer's images by name) + uint32 keypoint.
constexpr std::size_t kPointBytes = 3 * 8 + 3 + 4 + 2;

}  // namespace

std::int64_t store_alignment(Database& db, const LayerRecord& layer, const SiteInfo& site,
                             const StoredAlignment& a, const std::map<std::string, std::int64_t>& marker_ids) {
  // Replacing the sparse result invalidates everything derived from it.
  db.prepare("DELETE FROM reconstructions WHERE layer_id = ?").bind_all(layer.id).run();
  db.prepare("DELETE FROM camera_positions WHERE layer = ?").bind_all(layer.name).run();
  db.prepare(
        "INSERT INTO reconstructions(layer_id, stage, created_at, inputs_key, georeferenced, "
        "quality_json) VALUES (?, 'sparse', strftime('%Y-%m-%dT%H:%M:%SZ','now'), ?, ?, ?)")
      .bind_all(layer.id, a.inputs_key, a.rec.georeferenced ? 1 : 0, to_json(a.quality).dump())
      .run();
  const std::int64_t rid = db.last_insert_id();
  fault::point("process.align.reconstruction_inserted");

  for (std::size_t g = 0; g < a.rec.groups.size(); ++g) {
    const Intrinsics& k = a.rec.groups[g].intrinsics;
    db.prepare(
          "INSERT INTO solved_cameras(reconstruction_id, camera_id, width, height, fx, fy, cx, cy, "
          "k1, k2, model, k3, k4, p1, p2) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)")
        .bind_all(rid, a.camera_ids[g], k.width, k.height, k.fx, k.fy, k.cx, k.cy, k.k1, k.k2,
                  std::string(to_string(k.model)), k.k3, k.k4, k.p1, k.p2)
        .run();
  }
  auto pose_st = db.prepare(
      "INSERT INTO image_poses(reconstruction_id, image_id, registered, r11, r12, r13, r21, r22, "
      "r23, r31, r32, r33, cx_site, cy_site, cz_site) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
  auto cam_st = db.prepare(
      "INSERT INTO camera_positions(geom, layer, image, e, n, z) VALUES (?, ?, ?, ?, ?, ?)");
  for (std::size_t i = 0; i < a.rec.images.size(); ++i) {
    const auto& im = a.rec.images[i];
    pose_st.bind(1, rid).bind(2, a.images[i].id).bind(3, im.registered ? 1 : 0);
    if (im.registered) {
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) pose_st.bind(4 + 3 * r + c, im.pose.R(r, c));
      }
      const Eigen::Vector3d C = im.pose.centre();
      pose_st.bind(13, C.x()).bind(14, C.y()).bind(15, C.z());
      if (a.rec.georeferenced) {
        const Eigen::Vector3d w = C + site.origin;
        cam_st.bind_blob(1, gpkg_point_z(site.srs_id, w));
        cam_st.bind(2, layer.name).bind(3, im.name).bind(4, w.x()).bind(5, w.y()).bind(6, w.z());
        cam_st.run();
      }
    }
    pose_st.run();
  }
  fault::point("process.align.poses_written");
  std::vector<std::uint8_t> blob;
  blob.reserve(a.rec.points.size() * kPointBytes);
  for (const auto& p : a.rec.points) {
    put(blob, p.X.x());
    put(blob, p.X.y());
    put(blob, p.X.z());
    put(blob, p.colour(0));
    put(blob, p.colour(1));
    put(blob, p.colour(2));
    put(blob, float(p.error_px));
    const std::size_t n = std::min<std::size_t>(p.track.size(), 65535);
    put(blob, std::uint16_t(n));
    for (std::size_t t = 0; t < n; ++t) {
      put(blob, std::uint32_t(p.track[t].image));
      put(blob, std::uint32_t(p.track[t].keypoint));
    }
  }
  auto pts = db.prepare("INSERT INTO sparse_points(reconstruction_id, count, data) VALUES (?, ?, ?)");
  pts.bind(1, rid).bind(2, std::int64_t(a.rec.points.size()));
  pts.bind_blob(3, blob);
  pts.run();
  fault::point("process.align.points_written");

  auto res = db.prepare(
      "INSERT INTO marker_residuals(reconstruction_id, marker_id, role, triangulated, de, dn, dz, "
      "reprojection_px, images) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)");
  for (const MarkerResidual& r : a.quality.markers) {
    res.bind(1, rid).bind(2, marker_ids.at(r.name)).bind(3, std::string(to_string(r.role)));
    res.bind(4, r.triangulated ? 1 : 0);
    if (r.triangulated) res.bind(5, r.dE).bind(6, r.dN).bind(7, r.dZ).bind(8, r.reprojection_px);
    res.bind(9, r.images);
    res.run();
  }
  update_contents_extent(db, "camera_positions", "e", "n");
  return rid;
}

std::optional<StoredAlignment> load_alignment(Database& db, const LayerRecord& layer) {
  auto st = db.prepare(
      "SELECT id, georeferenced, quality_json, inputs_key FROM reconstructions WHERE layer_id = ? AND "
      "stage = 'sparse'");
  st.bind(1, layer.id);
  if (!st.step()) return std::nullopt;
  StoredAlignment a;
  a.reconstruction_id = st.get_int(0);
  a.rec.georeferenced = st.get_int(1) != 0;
  a.quality = alignment_quality_from_json(nlohmann::json::parse(st.get_text(2)));
  a.inputs_key = st.get_text(3);

  std::map<std::int64_t, int> group_of_camera;
  auto cams = db.prepare(
      "SELECT camera_id, width, height, fx, fy, cx, cy, k1, k2, model, k3, k4, p1, p2 FROM "
      "solved_cameras WHERE reconstruction_id = ? ORDER BY camera_id");
  cams.bind(1, a.reconstruction_id);
  while (cams.step()) {
    CameraGroup g;
    Intrinsics& k = g.intrinsics;
    k.width = int(cams.get_int(1));
    k.height = int(cams.get_int(2));
    k.fx = cams.get_double(3);
    k.fy = cams.get_double(4);
    k.cx = cams.get_double(5);
    k.cy = cams.get_double(6);
    k.k1 = cams.get_double(7);
    k.k2 = cams.get_double(8);
    const std::string model = cams.get_text(9);
    const auto m = camera_model_from_string(model);
    if (!m) {
      throw IoError(fmt::format("{}: solved_cameras row of camera {}: unknown lens model '{}'",
                                db.path().string(), cams.get_int(0), model));
    }
    k.model = *m;
    k.k3 = cams.get_double(10);
    k.k4 = cams.get_double(11);
    k.p1 = cams.get_double(12);
    k.p2 = cams.get_double(13);
    group_of_camera[cams.get_int(0)] = int(a.rec.groups.size());
    a.camera_ids.push_back(cams.get_int(0));
    a.rec.groups.push_back(g);
  }
  // Images in the order the pipeline stores them (by name), so that track image
  // indices stay valid.
  struct PoseRow {
    bool registered = false;
    Eigen::Matrix3d R;
    Eigen::Vector3d C;
  };
  std::map<std::int64_t, PoseRow> pose_of_image;
  auto poses = db.prepare(
      "SELECT image_id, registered, r11, r12, r13, r21, r22, r23, r31, r32, r33, cx_site, cy_site, "
      "cz_site FROM image_poses WHERE reconstruction_id = ?");
  poses.bind(1, a.reconstruction_id);
  while (poses.step()) {
    PoseRow row;
    row.registered = poses.get_int(1) != 0;
    if (row.registered) {
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) row.R(r, c) = poses.get_double(2 + 3 * r + c);
      }
      row.C = {poses.get_double(11), poses.get_double(12), poses.get_double(13)};
    }
    pose_of_image[poses.get_int(0)] = row;
  }
  for (const auto& im : list_images(db, layer.id)) {
    const auto it = pose_of_image.find(im.id);
    if (it == pose_of_image.end()) continue;
    RegisteredImage ri;
    ri.name = im.name;
    ri.group = im.camera_id ? group_of_camera[*im.camera_id] : 0;
    ri.registered = it->second.registered;
    if (ri.registered) ri.pose = Pose::from_centre(it->second.R, it->second.C);
    a.rec.images.push_back(ri);
    a.images.push_back(im);
  }
  auto pts = db.prepare("SELECT count, data FROM sparse_points WHERE reconstruction_id = ?");
  pts.bind(1, a.reconstruction_id);
  if (pts.step()) {
    const auto n = std::size_t(pts.get_int(0));
    const auto blob = pts.get_blob(1);
    std::size_t at = 0;
    a.rec.points.resize(n);
    for (auto& p : a.rec.points) {
      STRATA_CHECK(at + kPointBytes <= blob.size(), "sparse point blob truncated");
      p.X.x() = get<double>(blob, at);
      p.X.y() = get<double>(blob, at);
      p.X.z() = get<double>(blob, at);
      for (int c = 0; c < 3; ++c) p.colour(c) = get<std::uint8_t>(blob, at);
      p.error_px = get<float>(blob, at);
      const auto len = get<std::uint16_t>(blob, at);
      STRATA_CHECK(at + 8u * len <= blob.size(), "sparse point blob truncated");
      p.track.resize(len);
      for (auto& t : p.track) {
        t.image = int(get<std::uint32_t>(blob, at));
        t.keypoint = int(get<std::uint32_t>(blob, at));
      }
    }
  }
  return a;
}

}  // namespace strata
