#pragma once
// reader.ply: triangle meshes and point clouds (geometry/mesh.hpp) from the PLY
// files writer.ply (exporters/mesh) produces.
#include "geometry/mesh.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <string>
#include <vector>

namespace strata {

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

}  // namespace strata
