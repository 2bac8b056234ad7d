#include "pipeline/marker_workspace.hpp"

#include "core/field_error.hpp"
#include "pipeline/alignment_store.hpp"
#include "project/review_records.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <tuple>
#include <map>

namespace strata {
namespace {

using PairKey = std::pair<std::int64_t, std::int64_t>;  // (marker, image)

// A layer's observations and reviews, by (marker, image).
struct LayerObservations {
  std::map<PairKey, std::map<std::string, ObservationRecord>> by_source;  // source -> row
  std::map<PairKey, ObservationReview> reviews;

  LayerObservations(Database& db, std::int64_t layer_id) {
    for (const auto& o : list_observations(db, layer_id)) by_source[{o.marker_id, o.image_id}][o.source] = o;
    for (const auto& r : list_observation_reviews(db, layer_id)) reviews[{r.marker_id, r.image_id}] = r;
  }

  // The status of (marker, image), and the position behind it.
  ObservationStatus status(const PairKey& key, Eigen::Vector2d* pixel, std::string* source) const {
    const auto review = reviews.find(key);
    const auto rows = by_source.find(key);
    const auto row = [&](const char* s) -> const ObservationRecord* {
      if (rows == by_source.end()) return nullptr;
      const auto it = rows->second.find(s);
      return it == rows->second.end() ? nullptr : &it->second;
    };
    if (review != reviews.end() && review->second.verdict == "rejected") {
      *pixel = review->second.pixel;
      *source = review->second.source;
      return ObservationStatus::rejected;
    }
    const bool confirmed = review != reviews.end() && review->second.verdict == "confirmed";
    for (const char* s : {"clicked", "detected", "guided"}) {
      if (const auto* o = row(s)) {
        *pixel = o->pixel;
        *source = s;
        if (confirmed) return ObservationStatus::confirmed;
        return std::string(s) == "clicked"    ? ObservationStatus::clicked
               : std::string(s) == "detected" ? ObservationStatus::detected
                                              : ObservationStatus::predicted;
      }
    }
    return ObservationStatus::none;
  }
};

MarkerRecord marker_or_refuse(Database& db, const std::string& name) {
  auto m = find_marker(db, name);
  if (!m) throw FieldError("marker", name, fmt::format("marker '{}' is not in the survey (import markers first)", name));
  return *m;
}

ImageRecord photo_or_refuse(Database& db, const LayerRecord& layer, const std::string& photo) {
  for (const auto& im : list_images(db, layer.id)) {
    if (im.name == photo) return im;
  }
  throw FieldError("photo", photo, fmt::format("photo '{}' is not in layer {}", photo, layer.name));
}

const MarkerResidual* residual_of(const std::optional<StoredAlignment>& stored, const std::string& marker) {
  if (!stored) return nullptr;
  for (const auto& r : stored->quality.markers) {
    if (r.name == marker) return &r;
  }
  return nullptr;
}

// `marker_site`: the marker's surveyed position in the site frame (metres).
MarkerPhoto photo_entry(const Eigen::Vector3d& marker_site, const MarkerRecord& marker, const ImageRecord& image,
                        const std::optional<StoredAlignment>& stored, const LayerObservations& obs) {
  MarkerPhoto e;
  e.name = image.name;
  e.width = image.width;
  e.height = image.height;
  if (stored) {
    const auto& rec = stored->rec;
    for (std::size_t i = 0; i < stored->images.size(); ++i) {
      if (stored->images[i].id != image.id || !rec.images[i].registered) continue;
      e.registered = true;
      if (!rec.georeferenced) break;
      const Camera camera{rec.groups[std::size_t(rec.images[i].group)].intrinsics, rec.images[i].pose};
      e.predicted = camera.project(marker_site);
      // Inside the photo: the centres of the edge pixels are 0 and size - 1.
      e.sees = e.predicted && e.predicted->x() >= -0.5 && e.predicted->y() >= -0.5 &&
               e.predicted->x() <= image.width - 0.5 && e.predicted->y() <= image.height - 0.5;
      if (!e.sees) e.predicted.reset();
      break;
    }
  }
  Eigen::Vector2d pixel;
  e.status = obs.status({marker.id, image.id}, &pixel, &e.source);
  if (e.status != ObservationStatus::none) e.pixel = pixel;
  if (const MarkerResidual* r = residual_of(stored, marker.name)) {
    for (const auto& o : r->observations) {
      if (o.image_name == image.name && std::isfinite(o.to_survey_px)) e.residual_px = o.to_survey_px;
    }
  }
  return e;
}

MarkerPhoto entry_after_edit(Project& p, const LayerRecord& layer, const MarkerRecord& marker, const ImageRecord& image) {
  return photo_entry(marker.position - p.site().origin, marker, image, load_alignment(p.db(), layer),
                     LayerObservations(p.db(), layer.id));
}

}  // namespace

const char* to_string(ObservationStatus s) {
  switch (s) {
    case ObservationStatus::none: return "none";
    case ObservationStatus::clicked: return "clicked";
    case ObservationStatus::confirmed: return "confirmed";
    case ObservationStatus::predicted: return "predicted";
    case ObservationStatus::detected: return "detected";
    case ObservationStatus::rejected: return "rejected";
  }
  return "none";
}

MarkerOverview marker_overview(Project& p, const std::string& layer_name) {
  auto& db = p.db();
  const LayerRecord layer = require_layer(db, layer_name);
  const auto stored = load_alignment(db, layer);
  MarkerOverview out;
  out.layer = layer.name;
  out.aligned = stored.has_value();
  out.georeferenced = stored && stored->rec.georeferenced;
  if (out.georeferenced) {
    out.control_rmse = stored->quality.control_rmse;
    out.check_rmse = stored->quality.check_rmse;
  }
  const LayerObservations obs(db, layer.id);
  const auto images = list_images(db, layer.id);
  for (const auto& m : list_markers(db)) {
    WorkspaceMarker w;
    w.marker = m;
    for (const auto& im : images) {
      Eigen::Vector2d pixel;
      std::string source;
      switch (obs.status({m.id, im.id}, &pixel, &source)) {
        case ObservationStatus::clicked: ++w.counts.clicked; break;
        case ObservationStatus::confirmed: ++w.counts.confirmed; break;
        case ObservationStatus::predicted: ++w.counts.predicted; break;
        case ObservationStatus::detected: ++w.counts.detected; break;
        case ObservationStatus::rejected: ++w.counts.rejected; break;
        case ObservationStatus::none: break;
      }
    }
    if (const MarkerResidual* r = residual_of(stored, m.name)) w.residual = *r;
    out.markers.push_back(std::move(w));
  }
  return out;
}

MarkerPhotos marker_photos(Project& p, const std::string& layer_name, const std::string& marker_name) {
  auto& db = p.db();
  const LayerRecord layer = require_layer(db, layer_name);
  MarkerPhotos out;
  out.marker = marker_or_refuse(db, marker_name);
  const auto stored = load_alignment(db, layer);
  const LayerObservations obs(db, layer.id);
  const Eigen::Vector3d marker_site = out.marker.position - p.site().origin;  // read once, not per photo
  for (const auto& im : list_images(db, layer.id)) {
    out.photos.push_back(photo_entry(marker_site, out.marker, im, stored, obs));
  }
  const auto rank = [](const MarkerPhoto& e) { return e.status != ObservationStatus::none ? 0 : e.sees ? 1 : 2; };
  std::stable_sort(out.photos.begin(), out.photos.end(),
                   [&](const MarkerPhoto& a, const MarkerPhoto& b) { return rank(a) < rank(b); });
  return out;
}

MarkerPhoto click_marker(Project& p, const std::string& layer_name, const std::string& marker_name,
                         const std::string& photo, const Eigen::Vector2d& pixel) {
  auto& db = p.db();
  const LayerRecord layer = require_layer(db, layer_name);
  const MarkerRecord marker = marker_or_refuse(db, marker_name);
  const ImageRecord image = photo_or_refuse(db, layer, photo);
  // The photo spans -0.5 .. size - 0.5 (pixel centres at whole numbers).
  for (const auto& [field, v, size] : {std::tuple{"x", pixel.x(), image.width}, std::tuple{"y", pixel.y(), image.height}}) {
    if (!std::isfinite(v) || v < -0.5 || v > size - 0.5) {
      throw FieldError(field, fmt::format("{}", v),
                       fmt::format("{} {} is outside photo {} (0 to {} pixels)", field, v, photo, size - 1));
    }
  }
  Transaction tx(db);
  ObservationRecord o;
  o.marker_id = marker.id;
  o.image_id = image.id;
  o.pixel = pixel;
  o.source = "clicked";
  upsert_observation(db, o);
  clear_observation_review(db, marker.id, image.id);  // a person's own click replaces any verdict there
  tx.commit();
  return entry_after_edit(p, layer, marker, image);
}

ReviewVerdict parse_review_verdict(const std::string& text) {
  if (text == "confirmed") return ReviewVerdict::confirmed;
  if (text == "rejected") return ReviewVerdict::rejected;
  if (text == "cleared") return ReviewVerdict::cleared;
  throw FieldError("verdict", text, fmt::format("verdict '{}' is not confirmed, rejected or cleared", text));
}

MarkerPhoto review_observation(Project& p, const std::string& layer_name, const std::string& marker_name,
                               const std::string& photo, ReviewVerdict verdict) {
  auto& db = p.db();
  const LayerRecord layer = require_layer(db, layer_name);
  const MarkerRecord marker = marker_or_refuse(db, marker_name);
  const ImageRecord image = photo_or_refuse(db, layer, photo);
  const LayerObservations obs(db, layer.id);
  Eigen::Vector2d pixel;
  std::string source;
  const ObservationStatus status = obs.status({marker.id, image.id}, &pixel, &source);
  Transaction tx(db);
  if (verdict == ReviewVerdict::cleared) {
    if (status == ObservationStatus::none) {
      throw FieldError("photo", photo, fmt::format("marker {} has nothing in photo {} to clear", marker.name, photo));
    }
    // A confirmed guided position is a click made by the confirmation: withdrawn with it.
    const bool confirmed_guided = status == ObservationStatus::confirmed && obs.reviews.at({marker.id, image.id}).source == "guided";
    if (status == ObservationStatus::clicked || confirmed_guided) delete_observation(db, marker.id, image.id, "clicked");
    clear_observation_review(db, marker.id, image.id);
  } else {
    if (status != ObservationStatus::predicted && status != ObservationStatus::detected &&
        !(status == ObservationStatus::rejected && verdict == ReviewVerdict::confirmed) &&
        !(status == ObservationStatus::confirmed && verdict == ReviewVerdict::rejected)) {
      throw FieldError("verdict", verdict == ReviewVerdict::confirmed ? "confirmed" : "rejected",
                       fmt::format("marker {} in photo {} is {}: only a predicted or detected position is "
                                   "confirmed or rejected (a click is moved by clicking again, or cleared)",
                                   marker.name, photo, to_string(status)));
    }
    const std::string reviewed = status == ObservationStatus::rejected || status == ObservationStatus::confirmed
                                     ? obs.reviews.at({marker.id, image.id}).source
                                     : source;
    if (verdict == ReviewVerdict::confirmed && reviewed == "detected" && status == ObservationStatus::rejected) {
      // A rejected detection taken back: the next alignment detects it again.
      clear_observation_review(db, marker.id, image.id);
    } else {
      if (verdict == ReviewVerdict::confirmed && reviewed == "guided") {  // the position becomes a person's click
        upsert_observation(db, {0, marker.id, image.id, pixel, "clicked"});
        delete_observation(db, marker.id, image.id, "guided");
      } else if (verdict == ReviewVerdict::rejected) {
        delete_observation(db, marker.id, image.id, "guided");
        delete_observation(db, marker.id, image.id, "detected");
        if (reviewed == "guided") delete_observation(db, marker.id, image.id, "clicked");  // a confirmation withdrawn
      }
      set_observation_review(db, {marker.id, image.id, verdict == ReviewVerdict::confirmed ? "confirmed" : "rejected",
                                  reviewed, pixel, ""});
    }
  }
  tx.commit();
  return entry_after_edit(p, layer, marker, image);
}

}  // namespace strata
