#pragma once
// Plain triangle meshes and point clouds in the site frame, and the frame their
// exports are written in: the data the dense stage makes and the mesh writers
// (exporters/mesh) and readers (importers/mesh) carry. Eigen/std only.
#include <Eigen/Core>

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace strata {

using Rgb8 = Eigen::Matrix<std::uint8_t, 3, 1>;

// Vertices in the site frame (metres). A point cloud is a mesh without faces.
struct DenseMesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Rgb8> colours;              // empty or one per vertex
  std::vector<Eigen::Vector3f> normals;   // empty or one per vertex (unit)
  std::vector<std::array<int, 3>> faces;  // counter-clockwise seen from outside/above
};

// How exported coordinates are written.
struct ExportFrame {
  // true (default): double x, y, z in site CRS coordinates (site origin added back),
  // exact for CloudCompare/MeshLab/Blender users who shift on import.
  // false: float x, y, z in the local site frame, the offset in a header comment.
  bool crs_coordinates = true;
  Eigen::Vector3d site_origin = Eigen::Vector3d::Zero();  // E, N, Z, metres
  std::string crs;                                        // e.g. "EPSG:32636"; may be empty
};

// A mesh's texture as the model writers take it (exporters/gltf embeds the images,
// exporters/mesh writes them beside the OBJ): encoded atlas images and, per vertex,
// where it lies in its face's image.
struct MeshTexture {
  std::vector<Eigen::Vector2f> uv;       // per vertex; (0, 0) = the image's top-left corner (glTF's convention)
  std::vector<int> face_image;           // per face, index into images
  std::vector<std::string> images;       // encoded image files
  std::string mime_type = "image/jpeg";  // "image/jpeg" or "image/png"
};

// What makes a mesh (and its texture, when given) unfit to write, "" when nothing:
// attribute arrays whose length is not one per vertex, a face index out of range, a
// vertex that is not finite, UVs or face images that do not match, an image type other
// than JPEG or PNG. The writers prefix it with their stage and file.
std::string mesh_inconsistency(const DenseMesh& mesh, const MeshTexture* texture = nullptr);

// One unit normal per vertex, for writers that need a direction everywhere: the
// mesh's own normal, or, where that is unusable (not finite, shorter than 1e-6: a
// reader's zero fill, a degenerate fusion cell), the area-weighted normal of the faces
// around the vertex, +Z for an isolated one. Empty when the mesh has no normals.
std::vector<Eigen::Vector3f> unit_normals(const DenseMesh& mesh);

// The local origin the model exports (glTF, OBJ) write float-precision vertices
// relative to: the centre of the box lo..hi (site frame, metres) in site CRS
// coordinates, rounded to whole metres, so that it is short to quote and exact in
// float32. An empty box (lo above hi) stands for the site origin.
inline Eigen::Vector3d model_local_origin(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                                          const Eigen::Vector3d& site_origin) {
  const bool empty = !(lo.array() <= hi.array()).all();
  const Eigen::Vector3d centre = (empty ? Eigen::Vector3d::Zero() : Eigen::Vector3d(0.5 * (lo + hi))) + site_origin;
  return centre.array().round().matrix();
}

// The box of a mesh's vertices, grown into lo..hi (start with lo = +inf, hi = -inf).
inline void grow_box(const DenseMesh& mesh, Eigen::Vector3d& lo, Eigen::Vector3d& hi) {
  for (const auto& v : mesh.vertices) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
}

}  // namespace strata
