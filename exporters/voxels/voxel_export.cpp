// Exports of the label volume: GRASS 3D ASCII raster (writer.grass3d) and VTK
// image data (writer.vti). Plain text/binary writers, no OpenVDB here.
#include "exporters/voxels/voxel_export.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"

#include <fmt/format.h>

#include <bit>
#include <cstring>
#include <fstream>
#include <functional>

// The .vti appended block and its header are written as the host stores them.
static_assert(std::endian::native == std::endian::little, "writer.vti assumes a little-endian host");

namespace strata {
namespace fs = std::filesystem;
namespace {

// `path` written through a temporary name by `fill`, a stream on it.
void write_file(const fs::path& path, const char* stage, bool binary, const std::function<void(std::ofstream&)>& fill) {
  write_atomically(path, stage, [&](const fs::path& tmp) {
    std::ofstream out(tmp, binary ? std::ios::binary : std::ios::out);
    if (!out) throw IoError(fmt::format("{}: {}: cannot write", stage, tmp.string()));
    fill(out);
    out.close();  // the flush can fail (a full disk) as well as the write
    if (!out) throw IoError(fmt::format("{}: {}: write failed", stage, path.string()));
  });
}

// Real CRS bounds of the voxel block (outer faces, not centres).
struct Bounds {
  double west, east, south, north, bottom, top;
};
Bounds bounds_of(const LabelVolume& v) {
  const double h = v.voxel_size_m;
  const Eigen::Vector3d lo = v.min_centre + v.site_origin - Eigen::Vector3d::Constant(0.5 * h);
  return {lo.x(), lo.x() + v.nx * h, lo.y(), lo.y() + v.ny * h, lo.z(), lo.z() + v.nz * h};
}

}  // namespace

fs::path write_grass_ascii(const fs::path& path, const LabelVolume& v) {
  constexpr const char* kStage = "writer.grass3d";
  if (v.labels.empty()) throw ProcessingError(fmt::format("{}: the voxel model is empty", kStage));
  const Bounds b = bounds_of(v);
  write_file(path, kStage, false, [&](std::ofstream& out) {
    // Header of r3.in.ascii (GRASS 7+): rows north->south, levels bottom->top.
    out << "version: grass7\norder: nsbt\n";
    out << fmt::format("north: {:.4f}\nsouth: {:.4f}\neast: {:.4f}\nwest: {:.4f}\ntop: {:.4f}\nbottom: {:.4f}\n",
                       b.north, b.south, b.east, b.west, b.top, b.bottom);
    out << fmt::format("rows: {}\ncols: {}\nlevels: {}\n", v.ny, v.nx, v.nz);
    std::string line;
    for (int k = 0; k < v.nz; ++k)
      for (int j = v.ny - 1; j >= 0; --j) {
        line.clear();
        for (int i = 0; i < v.nx; ++i) {
          if (i) line += ' ';
          const std::int32_t label = v.at(i, j, k);
          if (label == 0) line += '*';
          else line += std::to_string(label);
        }
        line += '\n';
        out << line;
      }
  });
  // Legend: label -> unit code.
  const fs::path stem = path.parent_path() / path.stem();
  const fs::path legend = stem.string() + "_units.csv";
  write_file(legend, kStage, false, [&](std::ofstream& out) {
    out << "label,unit\n";
    for (const auto& [label, unit] : v.units) out << label << ',' << unit << '\n';
  });
  const fs::path script = stem.string() + ".sh";
  write_file(script, kStage, false, [&](std::ofstream& out) {
    out << "#!/bin/sh\n"
        << "# Imports the strata voxel model into GRASS as the 3D raster 'strata_units'\n"
        << "# (value = unit label; see " << legend.filename().string() << " for label -> unit code).\n"
        << "# Run inside a GRASS session whose location has the site CRS (" << v.crs << "), e.g.\n"
        << "#   grass --tmp-location " << v.crs << " --exec sh " << script.filename().string() << "\n"
        << "set -e\n"
        << "here=$(cd \"$(dirname \"$0\")\" && pwd)\n"
        << "r3.in.ascii --overwrite input=\"$here/" << path.filename().string()
        << "\" output=strata_units null_value='*'\n"
        << "g.region raster_3d=strata_units\n"
        << "r3.info map=strata_units\n";
  });
  fs::permissions(script, fs::perms::owner_exec | fs::perms::group_exec | fs::perms::others_exec,
                  fs::perm_options::add);
  return script;
}

void write_vti(const fs::path& path, const LabelVolume& v) {
  constexpr const char* kStage = "writer.vti";
  if (v.labels.empty()) throw ProcessingError(fmt::format("{}: the voxel model is empty", kStage));
  const Bounds b = bounds_of(v);
  const double h = v.voxel_size_m;
  std::string codes;
  for (const auto& [label, unit] : v.units) codes += fmt::format("{}{}={}", codes.empty() ? "" : ";", label, unit);
  const std::uint64_t bytes = v.labels.size() * sizeof(std::int32_t);
  write_file(path, kStage, true, [&](std::ofstream& out) {
    // Cell data: one value per voxel; the image's points are the voxel corners.
    out << "<?xml version=\"1.0\"?>\n"
        << "<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
        << fmt::format("  <ImageData WholeExtent=\"0 {} 0 {} 0 {}\" Origin=\"{:.4f} {:.4f} {:.4f}\" "
                       "Spacing=\"{} {} {}\">\n",
                       v.nx, v.ny, v.nz, b.west, b.south, b.bottom, h, h, h)
        << "    <FieldData>\n"
        << fmt::format("      <DataArray type=\"Float64\" Name=\"site_origin\" NumberOfTuples=\"3\" "
                       "format=\"ascii\">{:.4f} {:.4f} {:.4f}</DataArray>\n",
                       v.site_origin.x(), v.site_origin.y(), v.site_origin.z())
        << fmt::format("      <Array type=\"String\" Name=\"crs\" NumberOfTuples=\"1\" format=\"ascii\">", "");
    for (unsigned char c : v.crs) out << int(c) << ' ';
    out << "0</Array>\n"
        << "      <Array type=\"String\" Name=\"unit_codes\" NumberOfTuples=\"1\" format=\"ascii\">";
    for (unsigned char c : codes) out << int(c) << ' ';
    out << "0</Array>\n"
        << "    </FieldData>\n"
        << fmt::format("    <Piece Extent=\"0 {} 0 {} 0 {}\">\n", v.nx, v.ny, v.nz)
        << "      <CellData Scalars=\"unit\">\n"
        << "        <DataArray type=\"Int32\" Name=\"unit\" format=\"appended\" offset=\"0\"/>\n"
        << "      </CellData>\n"
        << "    </Piece>\n"
        << "  </ImageData>\n"
        << "  <AppendedData encoding=\"raw\">\n   _";
    out.write(reinterpret_cast<const char*>(&bytes), sizeof bytes);
    // VTK image order: x fastest, then y, then z: the same as LabelVolume.
    out.write(reinterpret_cast<const char*>(v.labels.data()), std::streamsize(bytes));
    out << "\n  </AppendedData>\n</VTKFile>\n";
  });
}

}  // namespace strata
