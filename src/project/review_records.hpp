#pragma once
// observation_reviews (schema 14): a person's confirmation or rejection of a guided or
// detected marker observation, and the deletion of one observation.
#include "project/database.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace strata {

struct ObservationReview {
  std::int64_t marker_id = 0;
  std::int64_t image_id = 0;
  std::string verdict;  // confirmed | rejected
  std::string source;   // guided | detected: what was reviewed
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
  std::string reviewed_at;  // ISO 8601 UTC; set by set_observation_review
};

// The reviews of a layer's photos (all of them without a layer), by image then marker.
std::vector<ObservationReview> list_observation_reviews(Database& db, std::optional<std::int64_t> layer_id = {});
// Inserts or replaces the review of (marker, image), stamping reviewed_at.
void set_observation_review(Database& db, const ObservationReview& review);
// Withdraws the review of (marker, image); false when there was none.
bool clear_observation_review(Database& db, std::int64_t marker_id, std::int64_t image_id);
// Deletes the observation of (marker, image) from `source`; false when there was none.
bool delete_observation(Database& db, std::int64_t marker_id, std::int64_t image_id, const std::string& source);

}  // namespace strata
