#include "importers/finds/find_importer.hpp"

#include "core/door.hpp"
#include "project/site_bounds.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "crs/crs.hpp"
#include "importers/markers/delimited.hpp"
#include "project/gpkg.hpp"
#include "project/records.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

namespace fs = std::filesystem;

namespace strata {
namespace {

constexpr const char* kCsvStage = "importer.finds.csv";
constexpr const char* kColumns = "id,E,N,Z,unit[,type][,description]";
// Coordinates that differ by less than this are the same survey (metres, or
// degrees * 1e-9 for geographic input, far below any survey precision).
constexpr double kSameCoordinateTolerance = 1e-6;

struct ParsedFind {
  FindRecord record;  // position still in the source CRS
  std::string at;     // "importer.finds.csv: finds.csv:12", for messages
  int line = 0;
};

bool same_find(const FindRecord& a, const FindRecord& b) {
  return (a.position - b.position).cwiseAbs().maxCoeff() <= kSameCoordinateTolerance && a.unit == b.unit &&
         a.type == b.type && a.description == b.description;
}

std::string describe(const FindRecord& f) {
  return fmt::format("unit {} at ({:.4f}, {:.4f}, {:.4f})", f.unit, f.position.x(), f.position.y(), f.position.z());
}

// Column order of the file: from its header when the first line has one.
struct Layout {
  enum Column { id, e, n, z, unit, type, description, count };
  std::vector<int> at = {0, 1, 2, 3, 4, 5, 6};
  std::size_t first_data = 0;
};

Layout read_layout(const DelimitedFile& df, const fs::path& file) {
  Layout layout;
  if (df.lines.empty() || df.lines[0].fields.size() < 2 || is_number(df.lines[0].fields[1])) return layout;
  const auto& header = df.lines[0];
  layout.at = header_columns(header, {{"id", "find", "find_id", "number", "no", "name"},
                                      {"e", "east", "easting", "x", "lon", "longitude"},
                                      {"n", "north", "northing", "y", "lat", "latitude"},
                                      {"z", "h", "height", "elevation", "elev"},
                                      {"unit", "context", "su", "us", "unit_code"},
                                      {"type", "material", "class", "category"},
                                      {"description", "desc", "notes", "note", "comment"}});
  const char* names[] = {"id", "E", "N", "Z", "unit"};
  for (int c = 0; c <= Layout::unit; ++c)
    if (layout.at[std::size_t(c)] < 0)
      throw InputError(fmt::format("{}: {}:{}: the header has no {} column (expected {})", kCsvStage, file.string(),
                                   header.number, names[c], kColumns));
  layout.first_data = 1;
  return layout;
}

std::vector<ParsedFind> parse_csv(const fs::path& file) {
  const DelimitedFile df = read_delimited(file);
  const Layout layout = read_layout(df, file);
  const int needed = 1 + *std::max_element(layout.at.begin(), layout.at.begin() + Layout::unit + 1);
  std::vector<ParsedFind> finds;
  std::map<std::string, std::size_t> seen;  // id -> index in finds
  const std::string joiner = df.delimiter == Delimiter::comma       ? ", "
                             : df.delimiter == Delimiter::semicolon ? "; "
                                                                    : " ";
  for (std::size_t i = layout.first_data; i < df.lines.size(); ++i) {
    const auto& line = df.lines[i];
    const auto& f = line.fields;
    ParsedFind p;
    p.line = line.number;
    p.at = fmt::format("{}: {}:{}", kCsvStage, file.string(), line.number);
    if (int(f.size()) < needed) {
      throw InputError(fmt::format("{}: expected {}, found {} field{}", p.at, kColumns, f.size(),
                                   f.size() == 1 ? "" : "s"));
    }
    auto field = [&](Layout::Column c) {
      const int k = layout.at[std::size_t(c)];
      return k >= 0 && k < int(f.size()) ? f[std::size_t(k)] : std::string();
    };
    p.record.id = field(Layout::id);
    if (!p.record.id.empty()) p.record.id = door::name_at(p.at, "find id", p.record.id);
    p.record.position = {parse_number(field(Layout::e), "E", p.at), parse_number(field(Layout::n), "N", p.at),
                         parse_number(field(Layout::z), "Z", p.at)};
    p.record.unit = field(Layout::unit);
    p.record.type = field(Layout::type);
    p.record.description = field(Layout::description);
    // A last-column description with the delimiter in it but no quotes ("rim sherd,
    // red slip", or words between spaces): the rest of the line.
    const int desc = layout.at[Layout::description];
    if (desc >= 0 && desc == *std::max_element(layout.at.begin(), layout.at.end())) {
      for (std::size_t k = std::size_t(desc) + 1; k < f.size(); ++k) p.record.description += joiner + f[k];
    }
    if (!p.record.unit.empty()) p.record.unit = door::name_at(p.at, "unit code", p.record.unit);
    p.record.type = door::text_at(p.at, "type", p.record.type);
    p.record.description = door::text_at(p.at, "description", p.record.description);
    auto [it, inserted] = seen.try_emplace(p.record.id, finds.size());
    if (!inserted) {
      const ParsedFind& first = finds[it->second];
      if (!same_find(first.record, p.record))
        throw InputError(fmt::format("{}: find '{}' appears again ({}) unlike on line {} ({})", p.at, p.record.id,
                                     describe(p.record), first.line, describe(first.record)));
      continue;
    }
    finds.push_back(std::move(p));
  }
  if (finds.empty()) throw InputError(fmt::format("{}: {}: no finds in the file", kCsvStage, file.string()));
  return finds;
}

// Checks what a line alone cannot: the id is given and the unit is in the project.
void require_known_units(Database& db, const std::vector<ParsedFind>& finds) {
  std::set<std::string> codes;
  for (const auto& u : list_units(db)) codes.insert(u.code);
  for (const auto& f : finds) {
    if (f.record.id.empty()) throw InputError(fmt::format("{}: the find id is empty", f.at));
    if (f.record.unit.empty()) throw InputError(fmt::format("{}: find '{}' has no unit", f.at, f.record.id));
    if (codes.count(f.record.unit)) continue;
    std::string known;
    for (const auto& c : codes) known += (known.empty() ? "" : ", ") + c;
    throw InputError(fmt::format("{}: find '{}': unit '{}' is not in the project ({}); add it with 'strata unit "
                                 "add' first",
                                 f.at, f.record.id, f.record.unit, known.empty() ? "it has no units" : "units " + known));
  }
}

FindImportSummary store_finds(Project& project, const FindImportOptions& options, std::vector<ParsedFind> finds,
                              const std::string& crs_context) {
  auto& db = project.db();
  const SiteInfo site = project.site();
  FindImportSummary summary;
  summary.source_crs = options.crs.empty() ? site.crs : options.crs;
  const CrsTransform to_site = transform_into_site(summary.source_crs, site.crs, crs_context);
  require_known_units(db, finds);
  fault::point("import.finds.parsed");

  Transaction tx(db);
  for (auto& f : finds) {
    try {
      f.record.position = to_site.apply(f.record.position);
    } catch (const CrsError& e) {
      throw CrsError(fmt::format("{}: {}", f.at, e.what()));
    }
    check_site_point(site, f.record.position, fmt::format("{}: find '{}'", f.at, f.record.id));
    if (auto existing = find_find(db, f.record.id)) {
      if (same_find(*existing, f.record)) {
        summary.finds_unchanged++;
        continue;
      }
      if (!options.update) {
        throw InputError(fmt::format("{}: find '{}' is already in the project ({}), this gives {}; use --update to "
                                     "replace it",
                                     f.at, f.record.id, describe(*existing), describe(f.record)));
      }
      summary.finds_updated++;
    } else {
      summary.finds_new++;
    }
    upsert_find(db, f.record, site.srs_id);
    fault::point("import.finds.find_written");
  }
  update_contents_extent(db, "finds", "e", "n");
  fault::point("import.finds.before_commit");
  tx.commit();
  return summary;
}

}  // namespace

FindImportSummary import_finds(Project& project, const FindImportOptions& options, const fs::path& file) {
  door::input_file(file, "finds CSV", door::kMaxTextFileBytes);
  std::vector<ParsedFind> finds = parse_csv(file);
  for (auto& f : finds) f.record.source = file.filename().string();
  return store_finds(project, options, std::move(finds), fmt::format("{}: {}", kCsvStage, file.string()));
}

FindImportSummary add_find(Project& project, const FindImportOptions& options, FindRecord find) {
  for (int axis = 0; axis < 3; ++axis)
    if (!std::isfinite(find.position[axis]))
      throw InputError(fmt::format("find add: --at {} '{}' is not a finite number", "ENZ"[axis], find.position[axis]));
  ParsedFind p;
  p.at = "find add";
  find.id = door::name_at(p.at, "--id", find.id);
  find.unit = door::name_at(p.at, "--unit", find.unit);
  find.type = door::text_at(p.at, "--type", find.type);
  find.description = door::text_at(p.at, "--description", find.description);
  p.record = std::move(find);
  p.record.source = "find add";
  return store_finds(project, options, {p}, "find add: --crs");
}

}  // namespace strata
