#pragma once
// importer.markers.csv and importer.markers.odm: surveyed markers (and, from
// OpenDroneMap gcp_list files, their image observations) into the project, in
// the site CRS. All or nothing: the first bad line aborts the whole import.
#include "project/project.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace strata {

enum class MarkerFormat { automatic, csv, odm };

struct MarkerImportOptions {
  MarkerFormat format = MarkerFormat::automatic;
  // CRS of the coordinates in the file. CSV: default the site CRS. ODM: the file's
  // first line, which this overrides when given. In a geographic CRS, E is the
  // longitude and N the latitude, in decimal degrees.
  std::string crs;
  // One-sigma survey precision (metres) for markers whose file gives none.
  double default_sigma = 0.01;
  // `default_sigma` is the survey's statement of its precision (--sigma was given),
  // not strata's default weight: the verdict then judges against it.
  bool sigma_stated = false;
  bool update = false;  // replace markers already in the project with new coordinates
  std::string layer;    // ODM: look up observed images in this layer only
  // ODM: observations of images that are not in the project (or not in `layer`) are
  // skipped and listed in the summary instead of refusing the file: a site-wide
  // gcp_list imported layer by layer. At least one observation must still match.
  bool skip_missing_images = false;
};

struct MarkerImportSummary {
  std::string format;      // "csv" | "odm"
  std::string source_crs;  // as used
  int markers_new = 0, markers_updated = 0, markers_unchanged = 0;
  int observations_new = 0, observations_updated = 0;
  std::vector<std::string> skipped;  // "file:line: image 'X'" per skipped observation
};

MarkerImportSummary import_markers(Project& project, const MarkerImportOptions& options,
                                   const std::filesystem::path& file);

MarkerFormat parse_marker_format(const std::string& text);  // csv|odm|auto

}  // namespace strata
