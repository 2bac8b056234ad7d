#include "project/depth_records.hpp"

#include "core/error.hpp"
#include "project/matrix_text.hpp"

namespace strata {
namespace {

constexpr const char* kSequenceSelect =
    "SELECT id, layer_id, name, width, height, fx, fy, cx, cy, depth_scale_m, noise_k, intrinsics_file, poses_file, "
    "imported_at FROM depth_sequences ";
constexpr const char* kFrameSelect =
    "SELECT id, sequence_id, frame, name, sha256, media_path, bytes, valid_pixels, colour_name, colour_sha256, "
    "colour_media_path, recorded_pose, pose, registered_by, registration_rms_m, registration_inliers, "
    "registration_sigma_t_m, registration_sigma_r_rad, min_x, min_y, min_z, max_x, max_y, max_z FROM depth_frames ";

std::optional<std::string> optional_text(const Statement& st, int col) {
  if (st.is_null(col)) return std::nullopt;
  return st.get_text(col);
}

DepthSequenceRecord read_sequence(const Statement& st) {
  DepthSequenceRecord s;
  s.id = st.get_int(0);
  s.layer_id = st.get_int(1);
  s.name = st.get_text(2);
  s.intrinsics = {int(st.get_int(3)), int(st.get_int(4)), st.get_double(5), st.get_double(6), st.get_double(7),
                  st.get_double(8)};
  s.depth_scale_m = st.get_double(9);
  s.noise_k = st.get_double(10);
  s.intrinsics_file = st.get_text(11);
  s.poses_file = optional_text(st, 12);
  s.imported_at = st.get_text(13);
  return s;
}

DepthFrameRecord read_frame(const Statement& st) {
  DepthFrameRecord f;
  f.id = st.get_int(0);
  f.sequence_id = st.get_int(1);
  f.frame = int(st.get_int(2));
  f.name = st.get_text(3);
  f.sha256 = st.get_text(4);
  f.media_path = st.get_text(5);
  f.bytes = st.get_int(6);
  f.valid_pixels = st.get_int(7);
  f.colour_name = optional_text(st, 8);
  f.colour_sha256 = optional_text(st, 9);
  f.colour_media_path = optional_text(st, 10);
  const std::string what = fmt::format("depth_frames: the pose of frame {}", f.id);
  if (!st.is_null(11)) f.recorded_pose = parse_matrix_text(st.get_text(11), what);
  if (!st.is_null(12)) f.pose = parse_matrix_text(st.get_text(12), what);
  if (!st.is_null(13)) {
    f.fit = DepthFrameFit{st.get_text(13), st.get_double(14), st.get_double(15), st.get_double(16),
                          st.get_double(17)};
  }
  if (!st.is_null(18)) {
    f.bounds = ScanBounds{{st.get_double(18), st.get_double(19), st.get_double(20)},
                          {st.get_double(21), st.get_double(22), st.get_double(23)}};
  }
  return f;
}

}  // namespace

std::int64_t insert_depth_sequence(Database& db, const DepthSequenceRecord& s) {
  auto st = db.prepare(
      "INSERT INTO depth_sequences(layer_id, name, width, height, fx, fy, cx, cy, depth_scale_m, noise_k, "
      "intrinsics_file, poses_file, imported_at) "
      "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, strftime('%Y-%m-%dT%H:%M:%SZ','now'))");
  st.bind_all(s.layer_id, s.name, s.intrinsics.width, s.intrinsics.height, s.intrinsics.fx, s.intrinsics.fy,
              s.intrinsics.cx, s.intrinsics.cy, s.depth_scale_m, s.noise_k, s.intrinsics_file, s.poses_file);
  st.run();
  return db.last_insert_id();
}

std::int64_t insert_depth_frame(Database& db, const DepthFrameRecord& f) {
  STRATA_CHECK(!f.pose, "a depth frame is registered after its import");
  auto st = db.prepare(
      "INSERT INTO depth_frames(sequence_id, frame, name, sha256, media_path, bytes, valid_pixels, colour_name, "
      "colour_sha256, colour_media_path, recorded_pose) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
  std::optional<std::string> recorded;
  if (f.recorded_pose) recorded = matrix_text(*f.recorded_pose);
  st.bind_all(f.sequence_id, f.frame, f.name, f.sha256, f.media_path, f.bytes, f.valid_pixels, f.colour_name,
              f.colour_sha256, f.colour_media_path, recorded);
  st.run();
  return db.last_insert_id();
}

void set_depth_frame_registered(Database& db, std::int64_t frame_id, const Eigen::Matrix4d& pose,
                                const ScanBounds& bounds, const DepthFrameFit& fit) {
  auto st = db.prepare(
      "UPDATE depth_frames SET pose = ?, registered_by = ?, registration_rms_m = ?, registration_inliers = ?, "
      "registration_sigma_t_m = ?, registration_sigma_r_rad = ?, min_x = ?, min_y = ?, min_z = ?, max_x = ?, "
      "max_y = ?, max_z = ? WHERE id = ?");
  st.bind_all(matrix_text(pose), fit.method, fit.rms_m, fit.inlier_share, fit.sigma_translation_m,
              fit.sigma_rotation_rad, bounds.min.x(), bounds.min.y(), bounds.min.z(), bounds.max.x(), bounds.max.y(),
              bounds.max.z(), frame_id);
  st.run();
  STRATA_CHECK(db.changes() == 1, "depth frame to register not found");
}

std::vector<DepthSequenceRecord> list_depth_sequences(Database& db, std::optional<std::int64_t> layer_id) {
  auto st = db.prepare(std::string(kSequenceSelect) + (layer_id ? "WHERE layer_id = ? " : "") + "ORDER BY id");
  if (layer_id) st.bind(1, *layer_id);
  std::vector<DepthSequenceRecord> out;
  while (st.step()) out.push_back(read_sequence(st));
  return out;
}

std::vector<DepthFrameRecord> list_depth_frames(Database& db, std::int64_t sequence_id) {
  auto st = db.prepare(std::string(kFrameSelect) + "WHERE sequence_id = ? ORDER BY frame");
  st.bind(1, sequence_id);
  std::vector<DepthFrameRecord> out;
  while (st.step()) out.push_back(read_frame(st));
  return out;
}

std::optional<DepthFrameRecord> find_depth_frame_by_sha(Database& db, const std::string& sha256) {
  auto st = db.prepare(std::string(kFrameSelect) + "WHERE sha256 = ?");
  st.bind(1, sha256);
  if (!st.step()) return std::nullopt;
  return read_frame(st);
}

}  // namespace strata
