// The marker workspace's routes (docs/api.yaml): the overview of a layer's markers, the
// photos of one marker, a click, a review, the guide, and the photos themselves.
// OpenCV (thumbnails) stays in this file.
#include "core/error.hpp"
#include "core/field_error.hpp"
#include "pipeline/guide_layer.hpp"
#include "pipeline/marker_workspace.hpp"
#include "project/records.hpp"
#include "server/http.hpp"

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <fstream>

namespace strata::server {
namespace fs = std::filesystem;
using httplib::Request;
using httplib::Response;
using nlohmann::json;

namespace {

json rmse_json(const std::optional<AxisRmse>& r) {
  if (!r || r->markers == 0) return nullptr;
  return {{"e_m", r->e}, {"n_m", r->n}, {"z_m", r->z}, {"xyz_m", r->xyz}, {"markers", r->markers}};
}

json pixel_json(const std::optional<Eigen::Vector2d>& p) {
  if (!p) return nullptr;
  return {p->x(), p->y()};
}

json photo_json(const MarkerPhoto& e) {
  json j = {{"name", e.name},
            {"width", e.width},
            {"height", e.height},
            {"registered", e.registered},
            {"sees", e.sees},
            {"predicted", pixel_json(e.predicted)},
            {"status", to_string(e.status)},
            {"residual_px", e.residual_px ? json(*e.residual_px) : json(nullptr)}};
  j["observation"] = e.pixel ? json{{"x", e.pixel->x()}, {"y", e.pixel->y()}, {"source", e.source}} : json(nullptr);
  return j;
}

// A marker the survey does not have is a 404 (the layer is checked first, layer_or_404).
template <class F>
auto marker_or_404(F&& f) {
  try {
    return f();
  } catch (const FieldError& e) {
    if (e.field() == "marker") throw HttpError(404, e.what(), e.field(), e.value());
    throw;
  }
}

void get_layer_markers(Context& c, const Request& req, Response& res) {
  Project p = c.read();
  const MarkerOverview o = marker_overview(p, layer_or_404(p, req.matches[1]).name);
  json markers = json::array();
  for (const auto& w : o.markers) {
    json m = {{"name", w.marker.name},
              {"role", w.marker.kind},
              {"e", w.marker.position.x()},
              {"n", w.marker.position.y()},
              {"z", w.marker.position.z()},
              {"counts",
               {{"clicked", w.counts.clicked},
                {"confirmed", w.counts.confirmed},
                {"predicted", w.counts.predicted},
                {"detected", w.counts.detected},
                {"rejected", w.counts.rejected}}}};
    m["residual"] = w.residual ? json{{"dE", w.residual->dE},
                                      {"dN", w.residual->dN},
                                      {"dZ", w.residual->dZ},
                                      {"reprojection_px", w.residual->reprojection_px},
                                      {"triangulated", w.residual->triangulated},
                                      {"images", w.residual->images}}
                               : json(nullptr);
    markers.push_back(m);
  }
  reply(res, 200,
        {{"layer", o.layer},
         {"aligned", o.aligned},
         {"georeferenced", o.georeferenced},
         {"control_rmse", rmse_json(o.control_rmse)},
         {"check_rmse", rmse_json(o.check_rmse)},
         {"markers", markers}});
}

void get_marker_photos(Context& c, const Request& req, Response& res) {
  Project p = c.read();
  const std::string layer = layer_or_404(p, req.matches[1]).name;
  const MarkerPhotos m = marker_or_404([&] { return marker_photos(p, layer, req.matches[2]); });
  json photos = json::array();
  for (const auto& e : m.photos) photos.push_back(photo_json(e));
  reply(res, 200, {{"marker", m.marker.name}, {"role", m.marker.kind}, {"photos", photos}});
}

void post_click(Context& c, const Request& req, Response& res) {
  const json body = json_body(req);
  const std::string photo = body_text(body, "photo", true);
  const Eigen::Vector2d pixel(body_number(body, "x"), body_number(body, "y"));
  ProjectWriter w = c.write(fmt::format("click marker {} in {}", std::string(req.matches[2]), photo));
  const std::string layer = layer_or_404(w.project, req.matches[1]).name;
  const MarkerPhoto e = marker_or_404([&] { return click_marker(w.project, layer, req.matches[2], photo, pixel); });
  reply(res, 201, photo_json(e));
}

void post_review(Context& c, const Request& req, Response& res) {
  const json body = json_body(req);
  const std::string photo = body_text(body, "photo", true);
  const ReviewVerdict verdict = parse_review_verdict(body_text(body, "verdict", true));
  ProjectWriter w = c.write(fmt::format("review marker {} in {}", std::string(req.matches[2]), photo));
  const std::string layer = layer_or_404(w.project, req.matches[1]).name;
  const MarkerPhoto e =
      marker_or_404([&] { return review_observation(w.project, layer, req.matches[2], photo, verdict); });
  reply(res, 200, photo_json(e));
}

void post_guide(Context& c, const Request& req, Response& res) {
  ProjectWriter w = c.write(fmt::format("markers guide --layer {}", std::string(req.matches[1])));
  const std::string layer = layer_or_404(w.project, req.matches[1]).name;
  const GuideLayerResult r = guide_layer(w.project, layer, MarkerGuideOptions{}, /*leave_out_single_clicks=*/true);
  json markers = json::array();
  for (const auto& m : r.summary.markers) {
    markers.push_back({{"name", m.name},
                       {"triangulated", m.triangulated},
                       {"added", m.added.size()},
                       {"rejected", m.rejected.size()},
                       {"message", m.message}});
  }
  reply(res, 200, {{"layer", r.layer}, {"guided", r.summary.added}, {"markers", markers},
                   {"left_out", r.single_clicks}});
}

// Photos are content-addressed: a URL always gives the same bytes.
constexpr const char* kImmutable = "private, max-age=31536000, immutable";

void get_photo(Context& c, const Request& req, Response& res) {
  Project p = c.read();
  const LayerRecord layer = layer_or_404(p, req.matches[1]);
  std::optional<ImageRecord> image;
  for (const auto& im : list_images(p.db(), layer.id)) {
    if (im.name == req.matches[2]) image = im;
  }
  if (!image) {
    throw HttpError(404, fmt::format("photo '{}' is not in layer {}", std::string(req.matches[2]), layer.name), "photo");
  }
  const fs::path file = c.dir / image->media_path;  // from the database, never from the request
  const std::string ext = file.extension().string();
  int max_px = 0;
  if (req.has_param("max")) {
    const std::string v = req.get_param_value("max");
    try {
      max_px = std::stoi(v);
    } catch (const std::exception&) {
      max_px = -1;
    }
    if (max_px < 16 || max_px > 4096) throw HttpError(400, fmt::format("max '{}' is not 16..4096 pixels", v), "max", v);
  }
  const bool browser_format = ext == ".jpg" || ext == ".jpeg" || ext == ".png";
  res.set_header("Cache-Control", kImmutable);
  if (max_px == 0 && browser_format) {
    std::ifstream in(file, std::ios::binary);
    if (!in) throw IoError(fmt::format("photo {}: {} cannot be read", image->name, image->media_path));
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    res.set_content(std::move(bytes), ext == ".png" ? "image/png" : "image/jpeg");
    return;
  }
  cv::Mat img = cv::imread(file.string(), cv::IMREAD_COLOR);
  if (img.empty()) throw IoError(fmt::format("photo {}: {} cannot be decoded", image->name, image->media_path));
  const int longer = std::max(img.cols, img.rows);
  if (max_px > 0 && longer > max_px) {
    const double s = double(max_px) / longer;
    cv::resize(img, img, cv::Size(std::max(1, int(std::lround(img.cols * s))), std::max(1, int(std::lround(img.rows * s)))),
               0, 0, cv::INTER_AREA);
  }
  std::vector<unsigned char> jpeg;
  cv::imencode(".jpg", img, jpeg, {cv::IMWRITE_JPEG_QUALITY, 85});
  res.set_content(reinterpret_cast<const char*>(jpeg.data()), jpeg.size(), "image/jpeg");
}

}  // namespace

std::vector<Route> marker_routes() {
  using R = Role;
  return {
      {{"GET", "/api/layers/{layer}/markers", R::viewer, "the markers of a layer, by status, with residuals"},
       get_layer_markers, {}},
      {{"GET", "/api/layers/{layer}/markers/{marker}", R::viewer, "the photos of the layer for one marker"},
       get_marker_photos, {}},
      {{"POST", "/api/layers/{layer}/markers/{marker}/clicks", R::recorder, "place the marker in a photo"}, post_click, {}},
      {{"POST", "/api/layers/{layer}/markers/{marker}/review", R::recorder, "confirm, reject or clear"}, post_review, {}},
      {{"POST", "/api/layers/{layer}/guide", R::recorder, "predict the clicked markers in every photo"}, post_guide, {}},
      {{"GET", "/api/layers/{layer}/photos/{photo}", R::viewer, "a photo, or its thumbnail"}, get_photo, {}},
  };
}

}  // namespace strata::server
