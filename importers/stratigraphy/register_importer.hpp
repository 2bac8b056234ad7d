#pragma once
// importer.units.csv and importer.relations.csv: a unit register and its relations
// as teams keep them in a spreadsheet (header row, quoted fields, comma, semicolon
// or tab). All or nothing: the first bad line aborts the whole import and the
// project stays as it was.
#include "project/project.hpp"

#include <filesystem>
#include <string>
#include <vector>

namespace strata {

struct UnitImportOptions {
  // A unit already in the project with another type or description is refused
  // unless this is set; then it is replaced. The same unit again is left as it is.
  bool update = false;
};

struct UnitImportSummary {
  int units_new = 0, units_updated = 0, units_unchanged = 0;
  std::vector<std::string> ignored_columns;  // header names strata does not record
};

struct RelationImportSummary {
  int relations_new = 0, relations_unchanged = 0;
  std::vector<std::string> ignored_columns;
};

// Columns code,type[,description], named in a header row (any case).
UnitImportSummary import_units(Project& project, const UnitImportOptions& options,
                               const std::filesystem::path& file);

// Columns a,relation,b, named in a header row (any case); every unit must already
// be in the project; a relation that would make the Harris matrix cyclic is refused
// with its line and the cycle.
RelationImportSummary import_relations(Project& project, const std::filesystem::path& file);

}  // namespace strata
