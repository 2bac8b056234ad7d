#pragma once
// Plain triangle meshes and point clouds of the dense stage, their writers
// (writer.ply, writer.obj) and CGAL processing (simplification, volume).
// Eigen/std only: CGAL stays in simplify.cpp.
#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <filesystem>
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

// Binary little-endian PLY, coloured when colours are present. Written to a
// temporary file beside `path`, then renamed. Throws IoError("writer.ply: ...").
void write_ply(const std::filesystem::path& path, const DenseMesh& mesh, const ExportFrame& frame);
// Wavefront OBJ with per-vertex colour ("v x y z r g b", MeshLab's extension).
void write_obj(const std::filesystem::path& path, const DenseMesh& mesh, const ExportFrame& frame);

// What read_ply found: coordinates exactly as stored in the file (CRS or local).
struct PlyContents {
  DenseMesh mesh;
  bool double_coordinates = false;
  bool has_offset_comment = false;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // from "comment strata_offset E N Z"
  std::string crs;                                   // from "comment crs ..."
  std::vector<std::string> header;                   // header lines, without newlines
};
// Reads the binary little-endian PLY files write_ply produces (and similar ones:
// float/double x,y,z, optional uchar colour, float normal, triangle faces).
PlyContents read_ply(const std::filesystem::path& path);

// Edge-collapse simplification (CGAL Surface_mesh_simplification, Lindstrom-Turk
// placement) to at most target_faces triangles. Colours and normals are dropped
// (the caller re-samples them). Returns the mesh unchanged when already small enough.
DenseMesh simplify_mesh(const DenseMesh& mesh, std::size_t target_faces);
// Volume bounded by a closed triangle mesh, cubic metres (CGAL
// Polygon_mesh_processing::volume). Throws ProcessingError when the mesh is not closed.
double closed_mesh_volume_m3(const DenseMesh& mesh);

}  // namespace strata
