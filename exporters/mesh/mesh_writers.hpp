#pragma once
// Writers of triangle meshes and point clouds (geometry/mesh.hpp): writer.ply,
// writer.obj.
#include "geometry/mesh.hpp"

#include <filesystem>

namespace strata {

// Binary little-endian PLY, coloured when colours are present. Written to a
// temporary file beside `path`, then renamed. Throws IoError("writer.ply: ...").
void write_ply(const std::filesystem::path& path, const DenseMesh& mesh, const ExportFrame& frame);
// Wavefront OBJ with per-vertex colour ("v x y z r g b", MeshLab's extension).
void write_obj(const std::filesystem::path& path, const DenseMesh& mesh, const ExportFrame& frame);

}  // namespace strata
