#pragma once
// Sections: a vertical profile along a line through every layer surface and unit
// solid, drawn as an archaeologist draws a section (SVG at 1:20) and written as
// 3D line features (GeoPackage). GDAL stays in section.cpp.
#include "volume/volume.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace strata {

// The profile along A -> B (site frame). Samples at chainage s (metres from A).
struct SectionProfile {
  Eigen::Vector2d a = Eigen::Vector2d::Zero(), b = Eigen::Vector2d::Zero();  // site frame XY
  std::vector<double> s;  // metres along the line
  struct Surface {
    std::string layer, unit;
    std::vector<double> z;  // site frame, NaN where unknown
  };
  struct Body {
    std::string unit;
    std::vector<double> top, bottom;  // site frame, NaN where the unit is absent
  };
  std::vector<Surface> surfaces;  // capture order
  std::vector<Body> bodies;       // excavated units, in order

  double length() const { return (b - a).norm(); }
  Eigen::Vector2d point(double chainage) const { return a + (b - a).normalized() * chainage; }
};

// Samples every layer surface and unit solid along A -> B every `step_m` metres
// (0: one grid cell). Throws InputError when the line is shorter than two steps.
SectionProfile cut_section(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                           const std::vector<LayerSurface>& layers, const std::vector<UnitSolid>& solids,
                           double step_m = 0);

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
// line, a 1 m scale bar, the ends A and B with their coordinates, a legend.
void write_section_svg(const std::filesystem::path& path, const SectionProfile& profile,
                       const Eigen::Vector3d& site_origin, const SectionDrawingOptions& options);

// GeoPackage with 3D lines in real CRS coordinates: table section_surfaces (one
// LINESTRING Z per layer and continuous stretch), table section_units (the closed
// outline of each unit's part as a LINESTRING Z) and section_line (A -> B).
void write_section_gpkg(const std::filesystem::path& path, const SectionProfile& profile,
                        const Eigen::Vector3d& site_origin, const std::string& crs);

}  // namespace strata
