#pragma once
// exporter.gltf: triangle meshes as one glTF 2.0 binary (.glb), vertex colours only
// (no textures yet).
//
// Frame. glTF stores float32 positions and is Y-up, metres. Site CRS coordinates at
// UTM magnitudes (E 734000, N 4174000) would lose about 0.5 m in float32, so the
// positions are relative to a local origin: the centre of the bounding box of all the
// meshes in the file, in site CRS coordinates, rounded to whole metres (exact in
// float32 too). Every node's `translation` is that origin, and the axes are mapped
//   glTF x = E, glTF y = Z (up), glTF z = -N
// (a rotation, so counter-clockwise faces stay counter-clockwise). A site CRS point is
// therefore (E, N, Z) = (t.x + p.x, -(t.z + p.z), t.y + p.y) for node translation t
// and position p. asset.extras records {"crs", "origin": [E, N, Z], "axes", "units"}.
//
// Per mesh: POSITION (float VEC3, min/max), NORMAL (float VEC3, unit length) when the
// mesh has normals, COLOR_0 (float VEC3, linear: glTF vertex colours are linear, the
// photos' colours sRGB) when it has colours, indices UNSIGNED_INT, one shared material
// (pbrMetallicRoughness: white, metallic 0, roughness 1, double-sided: an excavated
// surface is seen from below in sections).
#include "dense/dense_mesh.hpp"

#include <filesystem>
#include <span>
#include <string>

namespace strata {

struct GltfMesh {
  std::string name;                // node and mesh name (e.g. the layer); "" -> "mesh N"
  const DenseMesh* mesh = nullptr; // not owned; vertices in the site frame, at least one face
};

// Writes `meshes` to `path` (a staged name beside it, renamed when complete).
// frame.site_origin and frame.crs give the site CRS; frame.crs_coordinates is ignored
// (glTF always gets the local origin above). Throws InputError for a mesh without
// faces or with inconsistent arrays, IoError("exporter.gltf: <path>: ...") when the
// file cannot be written.
void write_glb(const std::filesystem::path& path, std::span<const GltfMesh> meshes, const ExportFrame& frame);

}  // namespace strata
