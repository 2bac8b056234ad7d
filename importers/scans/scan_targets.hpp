#pragma once
// importer.scan_targets: the surveyed targets a scanner measured in its own frame (the
// registration software's target list: spheres or checkerboards, each with the name
// of the surveyed marker it sits on), as CSV: name,x,y,z in metres, scanner frame.
// Delimiters, quotes, '#' comments and the header as for markers. One clear error
// naming file:line for a bad line, a name given twice or a file without targets.
#include <Eigen/Core>

#include <filesystem>
#include <string>
#include <vector>

namespace strata {

struct ScanTarget {
  std::string name;         // the surveyed marker it sits on
  Eigen::Vector3d scanner;  // metres, scanner frame
  int line = 0;             // in the file, for messages
};

std::vector<ScanTarget> read_scan_targets(const std::filesystem::path& file);

}  // namespace strata
