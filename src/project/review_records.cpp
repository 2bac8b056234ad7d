#include "project/review_records.hpp"

namespace strata {

std::vector<ObservationReview> list_observation_reviews(Database& db, std::optional<std::int64_t> layer_id) {
  std::string sql =
      "SELECT r.marker_id, r.image_id, r.verdict, r.source, r.x, r.y, r.reviewed_at FROM observation_reviews r "
      "JOIN images i ON i.id = r.image_id ";
  if (layer_id) sql += "WHERE i.layer_id = ? ";
  sql += "ORDER BY r.image_id, r.marker_id";
  auto st = db.prepare(sql);
  if (layer_id) st.bind(1, *layer_id);
  std::vector<ObservationReview> out;
  while (st.step()) {
    out.push_back({st.get_int(0), st.get_int(1), st.get_text(2), st.get_text(3),
                   Eigen::Vector2d(st.get_double(4), st.get_double(5)), st.get_text(6)});
  }
  return out;
}

void set_observation_review(Database& db, const ObservationReview& r) {
  db.prepare(
        "INSERT INTO observation_reviews(marker_id, image_id, verdict, source, x, y, reviewed_at) "
        "VALUES (?, ?, ?, ?, ?, ?, strftime('%Y-%m-%dT%H:%M:%SZ','now')) "
        "ON CONFLICT(marker_id, image_id) DO UPDATE SET verdict = excluded.verdict, source = excluded.source, "
        "x = excluded.x, y = excluded.y, reviewed_at = excluded.reviewed_at")
      .bind_all(r.marker_id, r.image_id, r.verdict, r.source, r.pixel.x(), r.pixel.y())
      .run();
}

bool clear_observation_review(Database& db, std::int64_t marker_id, std::int64_t image_id) {
  const bool existed =
      db.prepare("SELECT 1 FROM observation_reviews WHERE marker_id = ? AND image_id = ?").bind_all(marker_id, image_id).step();
  db.prepare("DELETE FROM observation_reviews WHERE marker_id = ? AND image_id = ?").bind_all(marker_id, image_id).run();
  return existed;
}

bool delete_observation(Database& db, std::int64_t marker_id, std::int64_t image_id, const std::string& source) {
  const bool existed = db.prepare("SELECT 1 FROM observations WHERE marker_id = ? AND image_id = ? AND source = ?")
                           .bind_all(marker_id, image_id, source)
                           .step();
  db.prepare("DELETE FROM observations WHERE marker_id = ? AND image_id = ? AND source = ?")
      .bind_all(marker_id, image_id, source)
      .run();
  return existed;
}

}  // namespace strata
