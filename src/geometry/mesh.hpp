#pragma once
// Plain triangle meshes and point clouds in the site frame, and the frame their
// exports are written in: the data the dense stage makes and the mesh writers
// (exporters/mesh) and readers (importers/mesh) carry. Eigen/std only.
#include <Eigen/Core>

#include <array>
#include <cstdint>
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

}  // namespace strata
