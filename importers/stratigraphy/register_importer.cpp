#include "importers/stratigraphy/register_importer.hpp"

#include "core/door.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "importers/markers/delimited.hpp"
#include "project/records.hpp"
#include "stratigraphy/harris_matrix.hpp"
#include "stratigraphy/recorded_matrix.hpp"

#include <fmt/ranges.h>

#include <algorithm>
#include <map>

namespace fs = std::filesystem;

namespace strata {
namespace {

constexpr const char* kUnitStage = "importer.units.csv";
constexpr const char* kRelationStage = "importer.relations.csv";

// A register's rows: the header names the columns (any order, any case); a line
// with more fields than the header has an unquoted delimiter in a value.
struct Register {
  struct Row {
    std::string at;  // "importer.units.csv: units.csv:12", for messages
    int line = 0;
    std::vector<std::string> values;  // one per wanted column, "" when absent
  };
  std::vector<Row> rows;
  std::vector<std::string> ignored_columns;
};

Register read_register(const fs::path& file, const char* stage, const std::vector<std::vector<std::string>>& aliases,
                       std::size_t required, const char* columns) {
  door::input_file(file, fmt::format("{}: register", stage), door::kMaxTextFileBytes);
  const DelimitedFile df = read_delimited(file);
  if (df.lines.empty()) throw InputError(fmt::format("{}: {}: the file is empty (expected a header {})", stage,
                                                     file.string(), columns));
  const DelimitedLine& header = df.lines[0];
  const std::vector<int> at = header_columns(header, aliases);
  for (std::size_t c = 0; c < required; ++c)
    if (at[c] < 0)
      throw InputError(fmt::format("{}: {}:{}: the header has no {} column (expected a header {})", stage,
                                   file.string(), header.number, aliases[c].front(), columns));
  Register reg;
  for (int i = 0; i < int(header.fields.size()); ++i)
    if (std::find(at.begin(), at.end(), i) == at.end()) reg.ignored_columns.push_back(header.fields[std::size_t(i)]);
  for (std::size_t k = 1; k < df.lines.size(); ++k) {
    const DelimitedLine& line = df.lines[k];
    Register::Row row{fmt::format("{}: {}:{}", stage, file.string(), line.number), line.number, {}};
    if (line.fields.size() > header.fields.size())
      throw InputError(fmt::format("{}: {} fields but the header names {} columns; put a value that holds the "
                                   "delimiter in double quotes",
                                   row.at, line.fields.size(), header.fields.size()));
    for (const int c : at)
      row.values.push_back(c >= 0 && c < int(line.fields.size()) ? line.fields[std::size_t(c)] : std::string());
    reg.rows.push_back(std::move(row));
  }
  if (reg.rows.empty()) throw InputError(fmt::format("{}: {}: no rows after the header", stage, file.string()));
  return reg;
}

struct ParsedUnit {
  UnitRecord record;
  std::string at;
  int line = 0;
};

bool same_unit(const UnitRecord& a, const UnitRecord& b) { return a.type == b.type && a.description == b.description; }

std::vector<ParsedUnit> parse_units(const fs::path& file, std::vector<std::string>& ignored) {
  Register reg = read_register(file, kUnitStage,
                               {{"code", "unit", "context", "su", "us"},
                                {"type", "kind", "category"},
                                {"description", "desc", "notes", "note", "comment"}},
                               2, "code,type[,description]");
  ignored = reg.ignored_columns;
  std::vector<ParsedUnit> units;
  std::map<std::string, std::size_t> seen;  // code -> index in units
  for (auto& row : reg.rows) {
    ParsedUnit u{{0, row.values[0], lower_case(row.values[1]), row.values[2]}, row.at, row.line};
    if (u.record.code.empty()) throw InputError(fmt::format("{}: the unit code is empty", u.at));
    u.record.code = door::name_at(u.at, "unit code", u.record.code);
    u.record.description = door::text_at(u.at, "description", u.record.description);
    const auto& types = unit_types();
    if (std::find(types.begin(), types.end(), u.record.type) == types.end())
      throw InputError(fmt::format("{}: unit '{}': type '{}' is not one of {}", u.at, u.record.code, row.values[1],
                                   fmt::join(types, ", ")));
    auto [it, inserted] = seen.try_emplace(u.record.code, units.size());
    if (!inserted) {
      if (!same_unit(units[it->second].record, u.record))
        throw InputError(fmt::format("{}: unit '{}' appears again, unlike on line {}", u.at, u.record.code,
                                     units[it->second].line));
      continue;
    }
    units.push_back(std::move(u));
  }
  return units;
}

}  // namespace

UnitImportSummary import_units(Project& project, const UnitImportOptions& options, const fs::path& file) {
  UnitImportSummary summary;
  const std::vector<ParsedUnit> units = parse_units(file, summary.ignored_columns);
  auto& db = project.db();
  fault::point("import.units.parsed");
  Transaction tx(db);
  for (const auto& u : units) {
    if (const auto existing = find_unit(db, u.record.code)) {
      if (same_unit(*existing, u.record)) {
        summary.units_unchanged++;
        continue;
      }
      if (!options.update)
        throw InputError(fmt::format("{}: unit '{}' is already in the project ({}, '{}'), this gives {}, '{}'; use "
                                     "--update to replace it",
                                     u.at, u.record.code, existing->type, existing->description, u.record.type,
                                     u.record.description));
      update_unit(db, u.record);
      summary.units_updated++;
    } else {
      insert_unit(db, u.record);
      summary.units_new++;
    }
    fault::point("import.units.unit_written");
  }
  fault::point("import.units.before_commit");
  tx.commit();
  return summary;
}

RelationImportSummary import_relations(Project& project, const fs::path& file) {
  RelationImportSummary summary;
  Register reg = read_register(file, kRelationStage,
                                     {{"a", "unit_a", "code_a", "from"},
                                      {"relation", "kind", "type", "relationship"},
                                      {"b", "unit_b", "code_b", "to"}},
                                     3, "a,relation,b");
  summary.ignored_columns = reg.ignored_columns;
  auto& db = project.db();
  HarrisMatrix matrix = recorded_matrix(db);
  const std::vector<std::string>& codes = matrix.units();
  fault::point("import.relations.parsed");
  Transaction tx(db);
  for (auto& row : reg.rows) {
    for (std::size_t c : {0, 2}) {
      if (!row.values[c].empty()) row.values[c] = door::name_at(row.at, "unit code", row.values[c]);
      const std::string& code = row.values[c];
      if (code.empty()) throw InputError(fmt::format("{}: the unit code in column {} is empty", row.at, "a b"[c]));
      if (std::find(codes.begin(), codes.end(), code) == codes.end())
        throw InputError(fmt::format("{}: unit '{}' is not in the project; import the unit register first "
                                     "('strata import units')",
                                     row.at, code));
    }
    try {
      const CanonicalRelation r = canonical_relation(row.values[0], row.values[1], row.values[2]);
      matrix.add(r);  // throws naming the cycle
      const bool added = insert_relation(db, {0, r.unit_a, to_string(r.kind), r.unit_b}) != 0;
      (added ? summary.relations_new : summary.relations_unchanged)++;
      if (added) fault::point("import.relations.relation_written");
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: {}", row.at, e.what()));
    }
  }
  fault::point("import.relations.before_commit");
  tx.commit();
  return summary;
}

}  // namespace strata
