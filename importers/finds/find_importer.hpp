#pragma once
// importer.finds.csv and `strata find add`: finds recorded in place by the total
// station (id,E,N,Z,unit[,type][,description]) into the project's finds table, in
// the site CRS. All or nothing: the first bad line, or a unit the project does not
// have, aborts the whole import and the project stays as it was.
#include "project/find_records.hpp"
#include "project/project.hpp"

#include <filesystem>
#include <string>

namespace strata {

struct FindImportOptions {
  // CRS of the coordinates given; default the site CRS. In a geographic CRS, E is
  // the longitude and N the latitude, in decimal degrees.
  std::string crs;
  // A find already in the project with another position, unit, type or description
  // is refused unless this is set; then it is replaced. The same find again is left
  // as it was (counted unchanged).
  bool update = false;
};

struct FindImportSummary {
  std::string source_crs;  // as used
  int finds_new = 0, finds_updated = 0, finds_unchanged = 0;
};

// Reads a finds CSV: header optional (without one the columns are
// id,E,N,Z,unit,type,description), comma, semicolon, tab or space separated.
FindImportSummary import_finds(Project& project, const FindImportOptions& options,
                               const std::filesystem::path& file);

// One find typed on the command line; `find.position` in options.crs (default the
// site CRS). The same checks as a line of the CSV.
FindImportSummary add_find(Project& project, const FindImportOptions& options, FindRecord find);

}  // namespace strata
