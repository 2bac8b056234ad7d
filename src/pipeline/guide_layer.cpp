#include "pipeline/guide_layer.hpp"

#include "core/error.hpp"
#include "pipeline/alignment_store.hpp"
#include "project/records.hpp"
#include "project/review_records.hpp"

#include <fmt/format.h>

#include <map>
#include <set>

namespace strata {
namespace {

struct LayerClicks {
  std::vector<GuideMarker> markers;
  std::vector<std::string> unregistered;
};

// The layer's clicks (and detections) by marker, on the registered photos.
LayerClicks collect_clicks(Database& db, const LayerRecord& layer, const std::map<std::int64_t, int>& photo_of_image,
                           const std::map<std::int64_t, std::string>& image_names) {
  std::map<std::int64_t, std::string> marker_names;
  for (const auto& m : list_markers(db)) marker_names[m.id] = m.name;
  std::map<std::int64_t, GuideMarker> by_marker;
  LayerClicks out;
  for (const auto& o : list_observations(db, layer.id)) {
    if (o.source == "guided") continue;
    const auto photo = photo_of_image.find(o.image_id);
    if (photo == photo_of_image.end()) {
      if (o.source == "clicked") {
        out.unregistered.push_back(fmt::format("{} in {}", marker_names.at(o.marker_id), image_names.at(o.image_id)));
      }
      continue;
    }
    GuideMarker& m = by_marker[o.marker_id];
    m.name = marker_names.at(o.marker_id);
    if (o.source == "clicked") {
      m.clicks.push_back({photo->second, o.pixel});
    } else {
      m.detected_in.push_back(photo->second);
    }
  }
  for (auto& [id, m] : by_marker) {
    if (m.clicks.empty()) continue;  // detected only: nothing to guide
    out.markers.push_back(std::move(m));
  }
  return out;
}

}  // namespace

GuideLayerResult guide_layer(Project& project, const std::string& layer_name, const MarkerGuideOptions& options,
                             bool leave_out_single_clicks) {
  options.validate();
  auto& db = project.db();
  const LayerRecord layer = require_layer(db, layer_name);
  const auto stored = load_alignment(db, layer);
  if (!stored) {
    throw ProcessingError(fmt::format(
        "layer {} is not aligned: run 'strata process {} --layer {} --until sparse' first (the guide predicts "
        "the clicked markers with the layer's cameras)",
        layer.name, project.dir().string(), layer.name));
  }
  if (!stored->rec.georeferenced) {
    throw ProcessingError(fmt::format(
        "layer {} is aligned but not georeferenced, so marker sizes in metres mean nothing in it: click at "
        "least 3 control markers in 2 photos each and run 'strata process {} --layer {} --until sparse' again",
        layer.name, project.dir().string(), layer.name));
  }
  GuideLayerResult result;
  result.layer = layer.name;
  GuideInput input;
  std::map<std::int64_t, int> photo_of_image;
  std::map<std::int64_t, std::string> image_names;
  const Reconstruction& rec = stored->rec;
  for (std::size_t i = 0; i < rec.images.size(); ++i) {
    const ImageRecord& img = stored->images[i];
    image_names[img.id] = img.name;
    if (!rec.images[i].registered) continue;
    photo_of_image[img.id] = int(input.photos.size());
    Camera cam{rec.groups[std::size_t(rec.images[i].group)].intrinsics, rec.images[i].pose};
    input.photos.push_back({img.name, project.dir() / img.media_path, cam});
    result.photo_names.push_back(img.name);
  }
  for (const auto& p : rec.points) input.sparse_points.push_back(p.X);
  LayerClicks clicks = collect_clicks(db, layer, photo_of_image, image_names);
  result.unregistered_clicks = clicks.unregistered;
  for (const auto& m : clicks.markers) {
    if (m.clicks.size() >= 2) continue;
    const std::string photo = input.photos[std::size_t(m.clicks.front().photo)].name;
    if (leave_out_single_clicks) {
      result.single_clicks.push_back(fmt::format("{} in {}", m.name, photo));
      continue;
    }
    throw InputError(fmt::format(
        "marker {} is clicked in only 1 registered photo of layer {} ({}): click it in at least one more "
        "photo (2-3 photos from different sides), then run 'strata markers guide' again",
        m.name, layer.name, photo));
  }
  std::erase_if(clicks.markers, [](const GuideMarker& m) { return m.clicks.size() < 2; });
  if (clicks.markers.empty()) {
    throw InputError(fmt::format(
        "layer {}: no marker is clicked in its registered photos; import clicks (an OpenDroneMap gcp_list, "
        "'strata import markers FILE --format odm') in 2-3 photos per marker first", layer.name));
  }
  input.markers = std::move(clicks.markers);
  result.summary = guide_markers(options, input);

  // Store: the layer's guided rows are replaced in one transaction.
  Transaction tx(db);
  result.replaced = int(db.query_int(fmt::format("SELECT count(*) FROM observations WHERE source = 'guided' AND "
                                                 "image_id IN (SELECT id FROM images WHERE layer_id = {})",
                                                 layer.id))
                            .value_or(0));
  db.prepare("DELETE FROM observations WHERE source = 'guided' AND image_id IN (SELECT id FROM images WHERE "
             "layer_id = ?)")
      .bind_all(layer.id)
      .run();
  std::map<std::string, std::int64_t> marker_ids;
  for (const auto& m : list_markers(db)) marker_ids[m.name] = m.id;
  std::map<int, std::int64_t> image_of_photo;
  for (const auto& [image, photo] : photo_of_image) image_of_photo[photo] = image;
  // A position a person rejected in the marker workspace is not placed again.
  std::set<std::pair<std::int64_t, std::int64_t>> rejected;
  for (const auto& r : list_observation_reviews(db, layer.id)) {
    if (r.verdict == "rejected") rejected.emplace(r.marker_id, r.image_id);
  }
  for (auto& m : result.summary.markers) {
    result.summary.added -= int(std::erase_if(m.added, [&](const GuidedObservation& g) {
      return rejected.count({marker_ids.at(m.name), image_of_photo.at(g.photo)}) > 0;
    }));
    for (const auto& g : m.added) {
      ObservationRecord o;
      o.marker_id = marker_ids.at(m.name);
      o.image_id = image_of_photo.at(g.photo);
      o.pixel = g.pixel;
      o.source = "guided";
      upsert_observation(db, o);
    }
  }
  tx.commit();
  return result;
}

}  // namespace strata
