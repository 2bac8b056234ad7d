#pragma once
// Exports of the label volume (geometry/label_volume.hpp) for GRASS (writer.grass3d) and
// ParaView (writer.vti). No OpenVDB here.
#include "geometry/label_volume.hpp"

#include <filesystem>

namespace strata {

// GRASS ASCII 3D raster for r3.in.ascii (header version grass7, order nsbt,
// real CRS bounds; null voxels "*") plus `<stem>.sh`, a script that imports it
// and sets the 3D region, and `<stem>_units.csv` (label,unit). Returns the
// script's path.
std::filesystem::path write_grass_ascii(const std::filesystem::path& path, const LabelVolume& volume);

// VTK XML ImageData (.vti) with cell data "unit" (Int32, raw appended). The
// origin is in real CRS coordinates; field data "site_origin" and "unit_codes".
void write_vti(const std::filesystem::path& path, const LabelVolume& volume);

}  // namespace strata
