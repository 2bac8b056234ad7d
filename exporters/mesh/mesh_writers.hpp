#pragma once
// Writers of triangle meshes and point clouds (geometry/mesh.hpp): writer.ply,
// writer.obj.
#include "geometry/mesh.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <vector>

namespace strata {

// Binary little-endian PLY, coloured when colours are present. Written to a
// temporary file beside `path`, then renamed. Throws IoError("writer.ply: ...").
void write_ply(const std::filesystem::path& path, const DenseMesh& mesh, const ExportFrame& frame);
// Wavefront OBJ with per-vertex colour ("v x y z r g b", MeshLab's extension) and
// normals (vn) when the mesh has them, in the frame `frame` says (the dense stage's
// mesh.obj).
void write_obj(const std::filesystem::path& path, const DenseMesh& mesh, const ExportFrame& frame);

// What write_obj_model wrote.
struct ObjModelFiles {
  std::filesystem::path obj, mtl;            // mtl: empty when untextured
  std::vector<std::filesystem::path> images;  // the atlases, beside the .obj
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // local origin, site CRS E, N, Z, whole metres
};

// exporter.obj: a mesh for viewers (Blender, MeshLab, CloudCompare, three.js), which
// read OBJ coordinates in float32. Vertices relative to the local origin the glTF
// export uses (model_local_origin: the mesh's box centre in site CRS coordinates,
// whole metres), in the site's axes: x = E, y = N, z = Z (up); the comment lines at
// the top give the CRS, the origin and the axes. Untextured: "v x y z r g b" with
// colours, vn with normals. With `texture`: vt (v = 0 the bottom of the image, as OBJ
// has it), one "usemtl atlas_K" group per image, FILE.mtl beside it whose map_Kd name
// the images, written beside as FILE_atlasK.jpg or .png (texture->mime_type). All
// files are staged and renamed into place together: a failure leaves none of them.
// Throws InputError for a mesh without faces, InternalError for inconsistent arrays,
// IoError("exporter.obj: <path>: ...") when a file cannot be written.
ObjModelFiles write_obj_model(const std::filesystem::path& path, const DenseMesh& mesh, const ExportFrame& frame,
                              const MeshTexture* texture = nullptr);

}  // namespace strata
