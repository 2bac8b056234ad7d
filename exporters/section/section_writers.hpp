#pragma once
// Writers of a section profile: the drawing as an archaeologist draws a section
// (writer.section.svg, at 1:20) and 3D line features (writer.section.gpkg). GDAL
// stays in section_writers.cpp.
#include "geometry/section_profile.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <map>
#include <string>

namespace strata {

struct SectionDrawingOptions {
  double scale = 20;           // drawing at 1:scale (1:20: 1 m = 50 mm on paper)
  std::string title = "Section";
  std::string crs;             // for the caption
  // unit code -> type (deposit|cut|structure|interface): cuts are written [105],
  // deposits (102), as on British and Italian context sheets.
  std::map<std::string, std::string> unit_types;
};

// SVG in millimetres at the drawing scale: units filled and labelled, layer
// surfaces as lines (the last, the limit of excavation, heavier), the unit not
// yet excavated hatched below it, a height scale in absolute metres, a datum
// line, a 1 m scale bar, the ends A and B with their coordinates, a legend; the
// finds projected onto the plane (profile.finds) as markers with their number,
// filled in front of the section face, open behind it.
void write_section_svg(const std::filesystem::path& path, const SectionProfile& profile,
                       const Eigen::Vector3d& site_origin, const SectionDrawingOptions& options);
// The same drawing as text (what write_section_svg writes; the field station sends it).
std::string section_svg(const SectionProfile& profile, const Eigen::Vector3d& site_origin,
                        const SectionDrawingOptions& options);

// GeoPackage with 3D lines in real CRS coordinates: table section_surfaces (one
// LINESTRING Z per layer and continuous stretch), table section_units (the closed
// outline of each unit's part as a LINESTRING Z) and section_line (A -> B); when
// finds were projected, section_finds (a POINT Z per find at its place on the plane:
// find_id, unit, type, chainage_m, height_m, offset_m, and the surveyed e, n).
void write_section_gpkg(const std::filesystem::path& path, const SectionProfile& profile,
                        const Eigen::Vector3d& site_origin, const std::string& crs);

}  // namespace strata
