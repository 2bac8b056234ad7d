#include "importers/vector/outline.hpp"

#include "core/door.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "crs/crs.hpp"
#include "project/site_bounds.hpp"

#include <fmt/format.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>

#include <cmath>
#include <memory>
#include <mutex>

namespace strata {
namespace fs = std::filesystem;
namespace {

constexpr const char* kStage = "reader.outline";

struct DatasetCloser {
  void operator()(GDALDataset* d) const { GDALClose(GDALDataset::ToHandle(d)); }
};
struct FeatureDeleter {
  void operator()(OGRFeature* f) const { OGRFeature::DestroyFeature(f); }
};

// The outer ring of the first polygon, in the file's coordinates, and the CRS its
// layer declares (null when none).
struct RawOutline {
  std::vector<Eigen::Vector2d> ring;
  std::unique_ptr<OGRSpatialReference> srs;
};

RawOutline first_polygon(GDALDataset& ds, const std::string& at) {
  RawOutline out;
  for (int li = 0; li < ds.GetLayerCount() && out.ring.empty(); ++li) {
    OGRLayer* layer = ds.GetLayer(li);
    layer->ResetReading();
    while (out.ring.empty()) {
      std::unique_ptr<OGRFeature, FeatureDeleter> f(layer->GetNextFeature());
      if (!f) break;
      const OGRGeometry* g = f->GetGeometryRef();
      const OGRPolygon* poly = nullptr;
      if (g && wkbFlatten(g->getGeometryType()) == wkbPolygon) poly = g->toPolygon();
      if (g && wkbFlatten(g->getGeometryType()) == wkbMultiPolygon && !g->toMultiPolygon()->IsEmpty())
        poly = g->toMultiPolygon()->getGeometryRef(0);
      if (!poly || !poly->getExteriorRing()) continue;
      const OGRLinearRing* r = poly->getExteriorRing();
      if (std::size_t(r->getNumPoints()) > kMaxOutlineVertices)
        throw InputError(fmt::format("{}: the polygon has {} vertices, more than {}", at, r->getNumPoints(),
                                     kMaxOutlineVertices));
      for (int i = 0; i < r->getNumPoints(); ++i) {
        if (!std::isfinite(r->getX(i)) || !std::isfinite(r->getY(i)))
          throw InputError(fmt::format("{}: vertex {} of the polygon is not a finite coordinate", at, i + 1));
        out.ring.emplace_back(r->getX(i), r->getY(i));
      }
      if (const OGRSpatialReference* srs = layer->GetSpatialRef()) out.srs.reset(srs->Clone());
    }
  }
  if (out.ring.empty()) throw InputError(fmt::format("{}: no polygon found", at));
  return out;
}

bool could_be_degrees(const std::vector<Eigen::Vector2d>& ring) {
  for (const auto& p : ring)
    if (std::abs(p.x()) > 360 || std::abs(p.y()) > 90) return false;
  return true;
}

double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

// Where the closed segments p0-p1 and q0-q1 meet, if they do (collinear overlaps: a
// point of the overlap).
std::optional<Eigen::Vector2d> crossing(const Eigen::Vector2d& p0, const Eigen::Vector2d& p1, const Eigen::Vector2d& q0,
                                        const Eigen::Vector2d& q1) {
  const Eigen::Vector2d r = p1 - p0, s = q1 - q0;
  const double denom = cross(r, s), scale = std::max({r.norm(), s.norm(), 1e-12});
  if (std::abs(denom) <= 1e-12 * scale * scale) {
    if (std::abs(cross(q0 - p0, r)) > 1e-9 * scale * scale) return std::nullopt;  // parallel, apart
    const double rr = r.squaredNorm();
    if (rr == 0) return std::nullopt;
    const double t0 = (q0 - p0).dot(r) / rr, t1 = (q1 - p0).dot(r) / rr;
    const double lo = std::max(0.0, std::min(t0, t1)), hi = std::min(1.0, std::max(t0, t1));
    if (lo > hi) return std::nullopt;
    return Eigen::Vector2d(p0 + 0.5 * (lo + hi) * r);
  }
  const double t = cross(q0 - p0, s) / denom, u = cross(q0 - p0, r) / denom;
  if (t < 0 || t > 1 || u < 0 || u > 1) return std::nullopt;
  return Eigen::Vector2d(p0 + t * r);
}

}  // namespace

void check_outline(const std::vector<Eigen::Vector2d>& ring_in, const SiteInfo& site, std::string_view what,
                   const std::optional<SiteExtent>& site_extent) {
  std::vector<Eigen::Vector2d> ring;  // without repeated vertices and the closing one
  for (const auto& p : ring_in)
    if (ring.empty() || (p - ring.back()).norm() > 1e-9) ring.push_back(p);
  while (ring.size() > 1 && (ring.front() - ring.back()).norm() <= 1e-9) ring.pop_back();
  if (ring.size() < 3)
    throw InputError(fmt::format("{}: the polygon has {} distinct vertices; an outline needs at least 3", what,
                                 ring.size()));
  for (std::size_t i = 0; i < ring.size(); ++i)
    check_site_position(site, ring[i] + site.origin.head<2>(), fmt::format("{}: vertex {}", what, i + 1));
  // Every pair of edges that are not neighbours: O(n^2), a few seconds at the vertex bound.
  const std::size_t n = ring.size();
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      if (j == i + 1 || (i == 0 && j == n - 1)) continue;  // neighbours share a vertex
      if (const auto x = crossing(ring[i], ring[(i + 1) % n], ring[j], ring[(j + 1) % n])) {
        const Eigen::Vector2d at = *x + site.origin.head<2>();
        throw InputError(fmt::format("{}: the polygon crosses itself (edge {}-{} meets edge {}-{} at E, N = {:.3f}, "
                                     "{:.3f}); draw it again without crossing, strata does not guess which part "
                                     "was meant",
                                     what, i + 1, (i + 1) % n + 1, j + 1, (j + 1) % n + 1, at.x(), at.y()));
      }
    }
  }
  double area2 = 0;
  for (std::size_t i = 0; i < ring.size(); ++i) area2 += cross(ring[i], ring[(i + 1) % ring.size()]);
  if (std::abs(area2) / 2 < 1e-6)
    throw InputError(fmt::format("{}: the polygon encloses no area ({:.2g} m2): its vertices lie on one line", what,
                                 std::abs(area2) / 2));
  if (site_extent) {
    Eigen::Vector2d lo = ring.front(), hi = ring.front();
    for (const auto& p : ring) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    const bool apart = (lo.array() > site_extent->max.array()).any() || (hi.array() < site_extent->min.array()).any();
    if (apart) {
      const Eigen::Vector2d o = site.origin.head<2>();
      throw InputError(fmt::format(
          "{}: the polygon (E {:.1f}..{:.1f}, N {:.1f}..{:.1f}) does not overlap the site's surfaces (E {:.1f}..{:.1f}, "
          "N {:.1f}..{:.1f}); is it in another CRS?",
          what, lo.x() + o.x(), hi.x() + o.x(), lo.y() + o.y(), hi.y() + o.y(), site_extent->min.x() + o.x(),
          site_extent->max.x() + o.x(), site_extent->min.y() + o.y(), site_extent->max.y() + o.y()));
    }
  }
}

std::vector<Eigen::Vector2d> read_outline(const fs::path& path, const SiteInfo& site, std::string_view what,
                                          const std::optional<SiteExtent>& site_extent) {
  const std::string at = fmt::format("{}: {}", kStage, what.empty() ? path.string() : fmt::format("{} {}", what, path.string()));
  door::input_file(path, fmt::format("{}: {}", kStage, what.empty() ? "outline" : what), 256ull << 20);
  static std::once_flag registered;
  std::call_once(registered, [] { GDALAllRegister(); });
  std::unique_ptr<GDALDataset, DatasetCloser> ds(GDALDataset::Open(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY));
  if (!ds) throw IoError(fmt::format("{}: cannot open as a vector file", at));
  RawOutline raw = first_polygon(*ds, at);
  // A GeoJSON without a "crs" member is WGS 84 to GDAL (RFC 7946), but projected
  // metres are not degrees: such a file was written in a projected CRS it does not name.
  if (raw.srs && raw.srs->IsGeographic() && !could_be_degrees(raw.ring)) raw.srs.reset();
  if (raw.srs) {
    OGRSpatialReference site_srs;
    site_srs.SetFromUserInput(describe_crs(site.crs).wkt.c_str());
    site_srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    raw.srs->SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    if (!raw.srs->IsSame(&site_srs)) {
      std::unique_ptr<OGRCoordinateTransformation> to_site(OGRCreateCoordinateTransformation(raw.srs.get(), &site_srs));
      if (!to_site)
        throw CrsError(fmt::format("{}: its CRS ({}) cannot be transformed into the site CRS {}", at,
                                   raw.srs->GetName() ? raw.srs->GetName() : "unnamed", site.crs));
      for (auto& p : raw.ring) {
        double x = p.x(), y = p.y();
        if (!to_site->Transform(1, &x, &y) || !std::isfinite(x) || !std::isfinite(y))
          throw CrsError(fmt::format("{}: vertex ({}, {}) cannot be transformed into the site CRS {}", at, p.x(), p.y(),
                                     site.crs));
        p = {x, y};
      }
      log::info("{}: transformed from {} into the site CRS {}", at, raw.srs->GetName() ? raw.srs->GetName() : "its CRS",
                site.crs);
    }
  }
  for (auto& p : raw.ring) p -= site.origin.head<2>();
  check_outline(raw.ring, site, at, site_extent);
  return raw.ring;
}

std::string outline_geojson(const std::vector<Eigen::Vector2d>& ring, const SiteInfo& site, std::string_view name) {
  const CrsInfo crs = describe_crs(site.crs);
  const std::string crs_name =
      crs.authority.empty() ? std::string() : fmt::format("urn:ogc:def:crs:{}::{}", crs.authority, crs.code);
  std::string coords;
  const bool closed = ring.front() == ring.back();
  for (std::size_t k = 0; k < ring.size() + (closed ? 0 : 1); ++k) {
    const Eigen::Vector2d& p = ring[k % ring.size()];
    coords += fmt::format("{}[{:.4f}, {:.4f}]", k ? ", " : "", p.x() + site.origin.x(), p.y() + site.origin.y());
  }
  return fmt::format("{{\"type\": \"FeatureCollection\", {}\"features\": [{{\"type\": \"Feature\", \"properties\": "
                     "{{\"name\": \"{}\"}}, \"geometry\": {{\"type\": \"Polygon\", \"coordinates\": [[{}]]}}}}]}}\n",
                     crs_name.empty() ? std::string()
                                      : fmt::format("\"crs\": {{\"type\": \"name\", \"properties\": {{\"name\": \"{}\"}}}}, ",
                                                    crs_name),
                     name, coords);
}

}  // namespace strata
