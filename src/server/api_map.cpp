// The map's routes (docs/api.yaml): what the map shows (rasters' bounds, markers,
// finds, contours and footprints), tiles cut from a layer's orthophoto and DTM, and a
// section drawn along a line. GDAL stays behind importers/raster; OpenCV (PNG) here.
//
// Tiles follow Leaflet's L.CRS.Simple in the site frame (E - origin E, N - origin N,
// metres): at zoom z a metre is 2^z pixels and tile (x, y) covers
// E - origin E in [x, x + 1] * 256 / 2^z and N - origin N in [-(y + 1), -y] * 256 / 2^z.
#include "core/error.hpp"
#include "importers/raster/geotiff.hpp"
#include "pipeline/site_section.hpp"
#include "project/find_records.hpp"
#include "project/records.hpp"
#include "project/site_plan_records.hpp"
#include "products/hillshade.hpp"
#include "server/http.hpp"

#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <charconv>
#include <cmath>

namespace strata::server {
namespace fs = std::filesystem;
using httplib::Request;
using httplib::Response;
using nlohmann::json;

namespace {

constexpr int kTilePx = 256;              // Leaflet's tile size
constexpr int kMinZoom = -4, kMaxZoom = 12;  // 1/16 px per metre (a 4 km tile) .. 4096 px per metre (0.25 mm)
constexpr long kMaxTileIndex = 1L << 24;  // beyond any site at any zoom; bounds the arithmetic
// The response of GET /api/map stays bounded whatever the layers hold: each line or
// ring is thinned evenly to at most kMaxLineVertices (its ends kept), and contour lines
// past kMaxMapVertices in all are left out (then "truncated": true).
constexpr std::size_t kMaxLineVertices = 400;
constexpr std::size_t kMaxMapVertices = 60000;
// A section line is refused when an end lies farther than this from the site origin
// east-west or north-south: a slip of the finger, not a section of this site. Metres.
constexpr double kMaxSectionOffset_m = 1000;

// ---- GET /api/map ---------------------------------------------------------------

std::vector<Eigen::Vector2d> thinned(const std::vector<Eigen::Vector2d>& pts) {
  if (pts.size() <= kMaxLineVertices) return pts;
  std::vector<Eigen::Vector2d> out;
  out.reserve(kMaxLineVertices);
  const double step = double(pts.size() - 1) / double(kMaxLineVertices - 1);
  for (std::size_t i = 0; i < kMaxLineVertices; ++i) out.push_back(pts[std::size_t(std::lround(i * step))]);
  return out;
}

json positions(const std::vector<Eigen::Vector2d>& pts) {
  json out = json::array();
  for (const auto& p : pts) out.push_back({p.x(), p.y()});
  return out;
}

json raster_json(const Context& c, const std::optional<ProductRecord>& product) {
  if (!product || !fs::exists(c.dir / product->path)) return nullptr;
  const RasterExtent e = read_raster_extent(c.dir / product->path);
  return {{"e_min", e.west}, {"n_min", e.south}, {"e_max", e.east}, {"n_max", e.north},
          {"pixel_m", e.pixel_m}, {"version", product->sha256.substr(0, 16)}};
}

void get_map(Context& c, const Request&, Response& res) {
  Project p = c.read();
  const SiteInfo site = p.site();
  json layers = json::array();
  json contours = {{"type", "FeatureCollection"}, {"features", json::array()}};
  json footprints = {{"type", "FeatureCollection"}, {"features", json::array()}};
  std::size_t vertices = 0;
  bool truncated = false;
  for (const auto& l : list_layers(p.db())) {
    const json ortho = raster_json(c, find_product(p.db(), l.id, "ortho"));
    const json dtm = raster_json(c, find_product(p.db(), l.id, "dtm"));
    if (ortho.is_null() && dtm.is_null()) continue;
    layers.push_back({{"name", l.name}, {"unit", l.unit}, {"ortho", ortho}, {"dtm", dtm}});
    for (const auto& f : list_footprints(p.db(), l.name)) {
      json polygons = json::array();
      for (const auto& poly : f.polygons) {
        json rings = json::array();
        for (const auto& ring : poly) {
          const auto t = thinned(ring);
          vertices += t.size();
          rings.push_back(positions(t));
        }
        polygons.push_back(rings);
      }
      footprints["features"].push_back({{"type", "Feature"},
                                        {"properties", {{"layer", l.name}, {"area_m2", f.area_m2}}},
                                        {"geometry", {{"type", "MultiPolygon"}, {"coordinates", polygons}}}});
    }
    for (const auto& line : list_contours(p.db(), l.name)) {
      const auto t = thinned(line.points);
      if (vertices + t.size() > kMaxMapVertices) {
        truncated = true;
        break;
      }
      vertices += t.size();
      contours["features"].push_back({{"type", "Feature"},
                                      {"properties", {{"layer", l.name}, {"elevation", line.elevation}}},
                                      {"geometry", {{"type", "LineString"}, {"coordinates", positions(t)}}}});
    }
  }
  json markers = json::array();
  for (const auto& m : list_markers(p.db())) {
    markers.push_back({{"name", m.name}, {"e", m.position.x()}, {"n", m.position.y()}, {"role", m.kind}});
  }
  json finds = json::array();
  for (const auto& f : list_finds(p.db())) {
    finds.push_back({{"id", f.id}, {"e", f.position.x()}, {"n", f.position.y()}, {"unit", f.unit}});
  }
  reply(res, 200,
        {{"crs", site.crs},
         {"origin", {site.origin.x(), site.origin.y(), site.origin.z()}},
         {"tiles", {{"size_px", kTilePx}, {"min_zoom", kMinZoom}, {"max_zoom", kMaxZoom}}},
         {"layers", layers},
         {"markers", markers},
         {"finds", finds},
         {"contours", contours},
         {"footprints", footprints},
         {"limits", {{"max_line_vertices", kMaxLineVertices}, {"max_vertices", kMaxMapVertices}}},
         {"truncated", truncated}});
}

// ---- GET /api/layers/{layer}/tiles/{kind}/{z}/{x}/{y} -----------------------------

long integer_segment(const std::string& text, const char* field, long lo, long hi) {
  long v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty()) {
    throw HttpError(400, fmt::format("{} '{}' is not an integer", field, text), field, text);
  }
  if (v < lo || v > hi) throw HttpError(400, fmt::format("{} {} is outside {}..{}", field, v, lo, hi), field, text);
  return v;
}

// The tile's PNG from its pixels: BGRA, transparent where `alpha` is 0.
std::string png(const cv::Mat& bgra) {
  std::vector<std::uint8_t> bytes;
  if (!cv::imencode(".png", bgra, bytes)) throw IoError("map tile: cannot encode the PNG");
  return {bytes.begin(), bytes.end()};
}

std::uint8_t byte_of(float v) { return std::uint8_t(std::clamp(std::lround(v), 0L, 255L)); }

cv::Mat ortho_tile(const fs::path& file, double west, double south, double east, double north) {
  const RasterThumbnail t = read_raster_window(file, west, south, east, north, kTilePx, kTilePx);
  cv::Mat out(kTilePx, kTilePx, CV_8UC4, cv::Scalar(0, 0, 0, 0));
  for (int row = 0; row < kTilePx; ++row) {
    for (int col = 0; col < kTilePx; ++col) {
      const std::size_t i = std::size_t(row) * kTilePx + std::size_t(col);
      if (!t.valid[i]) continue;
      const float r = t.band[0][i], g = t.bands >= 3 ? t.band[1][i] : r, b = t.bands >= 3 ? t.band[2][i] : r;
      const float a = t.bands == 4 ? t.band[3][i] : 255.0f;
      out.at<cv::Vec4b>(row, col) = {byte_of(b), byte_of(g), byte_of(r), byte_of(a)};
    }
  }
  return out;
}

// Hillshade of the DTM (products/hillshade.hpp), one tile read with a pixel more on
// every side for the 3x3 window at its edges.
cv::Mat hillshade_tile(const fs::path& file, double west, double south, double east, double north) {
  const double cell = (east - west) / kTilePx;  // metres per tile pixel
  const int n = kTilePx + 2;
  const RasterThumbnail t = read_raster_window(file, west - cell, south - cell, east + cell, north + cell, n, n);
  const std::vector<float> shade = hillshade({n, n, cell, cell, t.band[0].data(), t.valid.data()});
  cv::Mat out(kTilePx, kTilePx, CV_8UC4, cv::Scalar(0, 0, 0, 0));
  for (int row = 1; row <= kTilePx; ++row) {
    for (int col = 1; col <= kTilePx; ++col) {
      const float v = shade[std::size_t(row) * std::size_t(n) + std::size_t(col)];
      if (std::isnan(v)) continue;
      const std::uint8_t grey = byte_of(255 * v);
      out.at<cv::Vec4b>(row - 1, col - 1) = {grey, grey, grey, 255};
    }
  }
  return out;
}

void get_tile(Context& c, const Request& req, Response& res) {
  const std::string layer = req.matches[1], kind = req.matches[2];
  if (kind != "ortho" && kind != "hillshade") {
    throw HttpError(400, fmt::format("kind '{}' is not ortho or hillshade", kind), "kind", kind);
  }
  const int z = int(integer_segment(req.matches[3], "z", kMinZoom, kMaxZoom));
  const long x = integer_segment(req.matches[4], "x", -kMaxTileIndex, kMaxTileIndex);
  const long y = integer_segment(req.matches[5], "y", -kMaxTileIndex, kMaxTileIndex);
  Project p = c.read();
  const auto l = find_layer(p.db(), layer);
  if (!l) throw HttpError(404, fmt::format("layer '{}' does not exist", layer), "layer", layer);
  const char* product_kind = kind == "ortho" ? "ortho" : "dtm";
  const auto product = find_product(p.db(), l->id, product_kind);
  if (!product || !fs::exists(c.dir / product->path)) {
    throw HttpError(404, fmt::format("layer '{}' has no {}: process it to products first", layer,
                                     kind == "ortho" ? "orthophoto" : "DTM"), "layer", layer);
  }
  const Eigen::Vector3d origin = p.site().origin;
  const double size_m = kTilePx / std::ldexp(1.0, z);
  const double west = origin.x() + double(x) * size_m, north = origin.y() - double(y) * size_m;
  const fs::path file = c.dir / product->path;
  const cv::Mat tile = kind == "ortho" ? ortho_tile(file, west, north - size_m, west + size_m, north)
                                       : hillshade_tile(file, west, north - size_m, west + size_m, north);
  // The map asks with ?v= the product's version (GET /api/map): a reprocessed layer
  // gives another URL, so such a tile may be kept; any other is not.
  const bool versioned = req.has_param("v") && req.get_param_value("v") == product->sha256.substr(0, 16);
  res.set_header("Cache-Control", versioned ? "private, max-age=86400" : "no-store");
  res.status = 200;
  res.set_content(png(tile), "image/png");
}

// ---- POST /api/sections -----------------------------------------------------------

void post_section(Context& c, const Request& req, Response& res) {
  const json body = json_body(req);
  SiteSectionRequest r;
  r.a = {body_number(body, "e1"), body_number(body, "n1")};
  r.b = {body_number(body, "e2"), body_number(body, "n2")};
  if (r.a == r.b) throw HttpError(400, "the section line has no length: its two ends are the same point", "e2");
  Project p = c.read();
  const Eigen::Vector3d origin = p.site().origin;
  const std::pair<const char*, double> offsets[] = {{"e1", r.a.x() - origin.x()}, {"n1", r.a.y() - origin.y()},
                                                    {"e2", r.b.x() - origin.x()}, {"n2", r.b.y() - origin.y()}};
  for (const auto& [field, offset] : offsets) {
    if (std::abs(offset) > kMaxSectionOffset_m) {
      throw HttpError(400, fmt::format("{} is {:.0f} m from the site origin: a section must stay within {:.0f} m of it",
                                       field, std::abs(offset), kMaxSectionOffset_m),
                      field, fmt::format("{}", body.at(field).dump()));
    }
  }
  const SiteSection s = cut_site_section(p, SiteVolumeOptions{}, r);
  res.status = 200;
  res.set_header("Content-Disposition", "inline; filename=\"section.svg\"");
  res.set_content(section_svg(s.profile, s.site.origin, s.drawing), "image/svg+xml");
}

}  // namespace

std::vector<Route> map_routes() {
  using R = Role;
  return {
      {{"GET", "/api/map", R::viewer, "what the map shows: rasters' bounds, markers, finds, contours, footprints"},
       get_map, {}},
      {{"GET", "/api/layers/{layer}/tiles/{kind}/{z}/{x}/{y}", R::viewer, "a map tile of the layer's orthophoto or hillshade"},
       get_tile, {}},
      {{"POST", "/api/sections", R::viewer, "the section drawing (SVG) along a line"}, post_section, {}},
  };
}

}  // namespace strata::server
