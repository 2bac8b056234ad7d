#include "importers/markers/marker_importer.hpp"

#include "core/door.hpp"
#include "project/site_bounds.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "crs/crs.hpp"
#include "importers/markers/delimited.hpp"
#include "project/gpkg.hpp"
#include "project/records.hpp"

#include <algorithm>
#include <cctype>
#include <map>

namespace fs = std::filesystem;

namespace strata {
namespace {

// Coordinates that differ by less than this are the same survey (metres, or
// degrees * 1e-9 for geographic input, far below any survey precision).
constexpr double kSameCoordinateTolerance = 1e-6;

struct ParsedMarker {
  MarkerRecord record;  // position still in the source CRS
  bool has_sigma = false;
  int line = 0;
};

struct ParsedObservation {
  std::string marker;
  std::string image;
  Eigen::Vector2d pixel;
  int line = 0;
};

std::string where(const char* stage, const fs::path& file, int line) {
  return fmt::format("{}: {}:{}", stage, file.string(), line);
}

// Adds a marker to the parsed set, refusing a second, different position for a name.
void add_marker(std::map<std::string, ParsedMarker>& markers, ParsedMarker m, const char* stage,
                const fs::path& file) {
  auto [it, inserted] = markers.try_emplace(m.record.name, m);
  if (inserted) return;
  if ((it->second.record.position - m.record.position).cwiseAbs().maxCoeff() > kSameCoordinateTolerance) {
    throw InputError(fmt::format(
        "{}: marker '{}' appears again with different coordinates ({:.4f}, {:.4f}, {:.4f}) than on "
        "line {} ({:.4f}, {:.4f}, {:.4f})",
        where(stage, file, m.line), m.record.name, m.record.position.x(), m.record.position.y(),
        m.record.position.z(), it->second.line, it->second.record.position.x(),
        it->second.record.position.y(), it->second.record.position.z()));
  }
}

// importer.markers.csv: name,E,N,Z[,sigma][,kind], header optional.
std::map<std::string, ParsedMarker> parse_csv(const fs::path& file, double default_sigma) {
  constexpr const char* stage = "importer.markers.csv";
  const DelimitedFile df = read_delimited(file);
  std::map<std::string, ParsedMarker> markers;
  // Column positions, from the header when there is one.
  int c_name = 0, c_e = 1, c_n = 2, c_z = 3, c_sigma = -1, c_kind = -1;
  bool positional = true;
  std::size_t first = 0;
  if (!df.lines.empty() && df.lines[0].fields.size() >= 2 && !is_number(df.lines[0].fields[1])) {
    positional = false;
    c_name = c_e = c_n = c_z = -1;
    const auto& h = df.lines[0].fields;
    for (int i = 0; i < int(h.size()); ++i) {
      const std::string k = lower_case(h[i]);
      if (k == "name" || k == "id" || k == "marker" || k == "point" || k == "label") c_name = i;
      else if (k == "e" || k == "east" || k == "easting" || k == "x" || k == "lon" || k == "longitude") c_e = i;
      else if (k == "n" || k == "north" || k == "northing" || k == "y" || k == "lat" || k == "latitude") c_n = i;
      else if (k == "z" || k == "h" || k == "height" || k == "elevation" || k == "elev" || k == "alt") c_z = i;
      else if (k == "sigma" || k == "accuracy" || k == "precision" || k == "sd") c_sigma = i;
      else if (k == "kind" || k == "type" || k == "role" || k == "use") c_kind = i;
    }
    const std::pair<int, const char*> required[] = {{c_name, "name"}, {c_e, "E"}, {c_n, "N"}, {c_z, "Z"}};
    for (const auto& [col, label] : required) {
      if (col < 0) {
        throw InputError(fmt::format("{}: the header has no {} column (expected name,E,N,Z[,sigma][,kind])",
                                     where(stage, file, df.lines[0].number), label));
      }
    }
    first = 1;
  }
  for (std::size_t i = first; i < df.lines.size(); ++i) {
    const auto& line = df.lines[i];
    const std::string at = where(stage, file, line.number);
    const auto& f = line.fields;
    const int needed = std::max({c_name, c_e, c_n, c_z}) + 1;
    if (int(f.size()) < needed) {
      throw InputError(fmt::format("{}: expected name,E,N,Z[,sigma][,kind], found {} field{}", at,
                                   f.size(), f.size() == 1 ? "" : "s"));
    }
    ParsedMarker m;
    m.line = line.number;
    m.record.name = f[c_name];
    if (m.record.name.empty()) throw InputError(fmt::format("{}: marker name is empty", at));
    m.record.name = door::name_at(at, "marker name", m.record.name);
    m.record.position = {parse_number(f[c_e], "E", at), parse_number(f[c_n], "N", at),
                         parse_number(f[c_z], "Z", at)};
    double sigma = default_sigma;
    std::string kind = "control";
    if (positional) {
      // Optional 5th and 6th columns: sigma and/or kind, in that order.
      for (std::size_t k = 4; k < f.size(); ++k) {
        if (is_number(f[k]) || lower_case(f[k]) == "nan") {
          sigma = parse_number(f[k], "sigma", at);
          m.has_sigma = true;
        } else {
          kind = lower_case(f[k]);
        }
      }
    } else {
      if (c_sigma >= 0 && c_sigma < int(f.size()) && !f[c_sigma].empty()) {
        sigma = parse_number(f[c_sigma], "sigma", at);
        m.has_sigma = true;
      }
      if (c_kind >= 0 && c_kind < int(f.size()) && !f[c_kind].empty()) kind = lower_case(f[c_kind]);
    }
    if (sigma <= 0) throw InputError(fmt::format("{}: sigma {} must be positive (metres)", at, sigma));
    if (kind == "gcp") kind = "control";
    if (kind == "cp" || kind == "checkpoint") kind = "check";
    if (kind != "control" && kind != "check") {
      throw InputError(fmt::format("{}: kind '{}' is neither 'control' nor 'check'", at, kind));
    }
    m.record.sigma = Eigen::Vector3d::Constant(sigma);
    m.record.kind = kind;
    add_marker(markers, m, stage, file);
  }
  if (markers.empty()) throw InputError(fmt::format("{}: {}: no markers in the file", stage, file.string()));
  return markers;
}

// importer.markers.odm: first line a CRS, then "geo_x geo_y geo_z im_x im_y image [name]".
std::map<std::string, ParsedMarker> parse_odm(const fs::path& file, double default_sigma,
                                              std::string& crs_line,
                                              std::vector<ParsedObservation>& observations) {
  constexpr const char* stage = "importer.markers.odm";
  const DelimitedFile df = read_delimited(file, 1);
  crs_line = df.skipped.empty() ? "" : df.skipped[0];
  if (crs_line.empty()) throw InputError(fmt::format("{}: {}:1: the first line must name the CRS", stage, file.string()));
  std::map<std::string, ParsedMarker> markers;
  std::map<std::tuple<double, double, double>, std::string> unnamed;
  for (const auto& line : df.lines) {
    const std::string at = where(stage, file, line.number);
    const auto& f = line.fields;
    if (f.size() < 6) {
      throw InputError(fmt::format("{}: expected 'geo_x geo_y geo_z im_x im_y image [name]', found {} field{}",
                                   at, f.size(), f.size() == 1 ? "" : "s"));
    }
    ParsedMarker m;
    m.line = line.number;
    m.record.position = {parse_number(f[0], "geo_x", at), parse_number(f[1], "geo_y", at),
                         parse_number(f[2], "geo_z", at)};
    const Eigen::Vector2d pixel(parse_number(f[3], "im_x", at), parse_number(f[4], "im_y", at));
    if (pixel.x() < 0 || pixel.y() < 0) {
      throw InputError(fmt::format("{}: pixel ({}, {}) lies outside the image", at, pixel.x(), pixel.y()));
    }
    if (f.size() >= 7) {
      m.record.name = door::name_at(where(stage, file, line.number), "marker name", f[6]);
    } else {
      // ODM allows unnamed points: the same coordinates are the same marker.
      auto key = std::make_tuple(m.record.position.x(), m.record.position.y(), m.record.position.z());
      auto [it, inserted] = unnamed.try_emplace(key, fmt::format("gcp{}", unnamed.size() + 1));
      m.record.name = it->second;
    }
    m.record.sigma = Eigen::Vector3d::Constant(default_sigma);
    m.record.kind = "control";
    add_marker(markers, m, stage, file);
    observations.push_back({m.record.name, fs::path(f[5]).filename().string(), pixel, line.number});
  }
  if (markers.empty()) throw InputError(fmt::format("{}: {}: no observations in the file", stage, file.string()));
  return markers;
}

MarkerFormat detect_format(const fs::path& file) {
  const DelimitedFile df = read_delimited(file);
  if (df.lines.empty()) return MarkerFormat::csv;
  const auto& first = df.lines.front().fields;
  const auto numeric = std::count_if(first.begin(), first.end(), [](const std::string& f) { return is_number(f); });
  if (numeric >= 3) return MarkerFormat::csv;
  if (df.lines.size() >= 2 && df.lines[1].fields.size() >= 6 && is_number(df.lines[1].fields[3]) &&
      is_number(df.lines[1].fields[4])) {
    std::string line;
    for (const auto& f : first) line += (line.empty() ? "" : " ") + f;
    // A CRS line has letters (EPSG:, +proj=, WKT, a name); one of digits and signs is a
    // data line, and asking PROJ would search its whole database for that name (0.2 s,
    // seconds under the fuzzer's sanitizers: its only slow inputs, docs/reliability.md).
    const bool letters = std::any_of(line.begin(), line.end(), [](unsigned char c) { return std::isalpha(c); });
    if (!letters) return MarkerFormat::csv;
    try {
      describe_crs(line);
      return MarkerFormat::odm;
    } catch (const CrsError&) {
    }
  }
  return MarkerFormat::csv;
}

}  // namespace

MarkerFormat parse_marker_format(const std::string& text) {
  const std::string t = lower_case(text);
  if (t == "csv") return MarkerFormat::csv;
  if (t == "odm" || t == "gcp") return MarkerFormat::odm;
  if (t == "auto" || t.empty()) return MarkerFormat::automatic;
  throw InputError(fmt::format("unknown marker format '{}'; use csv or odm", text));
}

MarkerImportSummary import_markers(Project& project, const MarkerImportOptions& options,
                                   const fs::path& file) {
  door::input_file(file, "marker file", door::kMaxTextFileBytes);
  if (!(options.default_sigma > 0)) throw InputError(fmt::format("--sigma {} must be positive (metres)", options.default_sigma));
  auto& db = project.db();
  const SiteInfo site = project.site();
  MarkerFormat format = options.format == MarkerFormat::automatic ? detect_format(file) : options.format;

  MarkerImportSummary summary;
  std::map<std::string, ParsedMarker> markers;
  std::vector<ParsedObservation> observations;
  std::string source_crs = site.crs;
  if (format == MarkerFormat::odm) {
    summary.format = "odm";
    std::string crs_line;
    markers = parse_odm(file, options.default_sigma, crs_line, observations);
    source_crs = options.crs.empty() ? crs_line : options.crs;
  } else {
    summary.format = "csv";
    markers = parse_csv(file, options.default_sigma);
    if (!options.crs.empty()) source_crs = options.crs;
  }
  const std::string stage = "importer.markers." + summary.format;
  // A CRS PROJ knows may still have no transformation to the site CRS (e.g. a
  // projection string without a datum): both are refused naming the file.
  const CrsTransform to_site = transform_into_site(source_crs, site.crs, fmt::format("{}: {}", stage, file.string()));
  summary.source_crs = source_crs;

  // Resolve every observed image before writing anything.
  std::optional<std::int64_t> layer_id;
  if (!options.layer.empty()) layer_id = require_layer(db, options.layer).id;
  std::vector<std::int64_t> image_ids;
  std::vector<ParsedObservation> kept;
  for (const auto& o : observations) {
    std::vector<ImageRecord> found = find_images_by_name(db, o.image);
    if (layer_id) {
      std::erase_if(found, [&](const ImageRecord& im) { return im.layer_id != *layer_id; });
    }
    const std::string at = where(stage.c_str(), file, o.line);
    if (found.empty() && options.skip_missing_images) {
      summary.skipped.push_back(fmt::format("{}: image '{}'", at, o.image));
      continue;
    }
    if (found.empty()) {
      throw InputError(fmt::format("{}: image '{}' is not in the project{}; import the photos first",
                                   at, o.image, layer_id ? " (layer " + options.layer + ")" : ""));
    }
    if (found.size() > 1) {
      throw InputError(fmt::format("{}: image name '{}' is in {} layers; choose one with --layer", at,
                                   o.image, found.size()));
    }
    image_ids.push_back(found.front().id);
    kept.push_back(o);
  }
  if (!observations.empty() && kept.empty()) {
    throw InputError(fmt::format("{}: {}: none of the {} observed images is in the project{}; import the "
                                 "photos first",
                                 stage, file.string(), observations.size(),
                                 layer_id ? " (layer " + options.layer + ")" : ""));
  }
  observations = std::move(kept);
  fault::point("import.markers.parsed");

  // Every marker a place of the site: near its origin, or, for the survey that will
  // fix the origin, near the first marker of the file.
  SiteInfo bounds = site;
  for (auto& [name, m] : markers) {
    const std::string at = where(stage.c_str(), file, m.line);
    try {
      m.record.position = to_site.apply(m.record.position);
    } catch (const CrsError& e) {
      throw CrsError(fmt::format("{}: {}", at, e.what()));
    }
    check_site_point(bounds, m.record.position, fmt::format("{}: marker '{}'", at, name));
    if (!bounds.origin_set) {
      bounds.origin = m.record.position;
      bounds.origin_set = true;
    }
  }

  Transaction tx(db);
  std::map<std::string, std::int64_t> marker_ids;
  for (auto& [name, m] : markers) {
    const std::string at = where(stage.c_str(), file, m.line);
    m.record.source = file.filename().string();
    m.has_sigma = m.has_sigma || options.sigma_stated;
    m.record.sigma_stated = m.has_sigma;
    if (auto existing = find_marker(db, name)) {
      const bool same = (existing->position - m.record.position).cwiseAbs().maxCoeff() <= kSameCoordinateTolerance;
      if (!same && !options.update) {
        throw InputError(fmt::format(
            "{}: marker '{}' is already in the project at ({:.4f}, {:.4f}, {:.4f}), this file gives "
            "({:.4f}, {:.4f}, {:.4f}); use --update to replace it",
            at, name, existing->position.x(), existing->position.y(), existing->position.z(),
            m.record.position.x(), m.record.position.y(), m.record.position.z()));
      }
      if (!m.has_sigma) {
        m.record.sigma = existing->sigma;
        m.record.sigma_stated = existing->sigma_stated;
      }
      if (format == MarkerFormat::odm) m.record.kind = existing->kind;  // ODM has no kind
      const bool unchanged = same && existing->sigma == m.record.sigma &&
                             existing->sigma_stated == m.record.sigma_stated && existing->kind == m.record.kind;
      marker_ids[name] = unchanged ? existing->id : upsert_marker(db, m.record, site.srs_id);
      (unchanged ? summary.markers_unchanged : summary.markers_updated)++;
    } else {
      marker_ids[name] = upsert_marker(db, m.record, site.srs_id);
      summary.markers_new++;
    }
    fault::point("import.markers.marker_written");
  }
  for (std::size_t i = 0; i < observations.size(); ++i) {
    ObservationRecord o;
    o.marker_id = marker_ids.at(observations[i].marker);
    o.image_id = image_ids[i];
    o.pixel = observations[i].pixel;
    o.source = "clicked";
    (upsert_observation(db, o) ? summary.observations_new : summary.observations_updated)++;
    fault::point("import.markers.observation_written");
  }
  update_contents_extent(db, "markers", "e", "n");
  const auto all = list_markers(db);
  if (!all.empty()) project.set_origin_if_unset(all.front().position);
  fault::point("import.markers.before_commit");
  tx.commit();
  return summary;
}

}  // namespace strata
