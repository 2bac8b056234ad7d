#include "geometry/mesh.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <string>

namespace strata {
namespace {

std::string count_mismatch(std::size_t n, const char* what, std::size_t expected, const char* of) {
  return std::to_string(n) + " " + what + " for " + std::to_string(expected) + " " + of;
}

std::string texture_inconsistency(const DenseMesh& mesh, const MeshTexture& t) {
  if (t.uv.size() != mesh.vertices.size()) return count_mismatch(t.uv.size(), "UVs", mesh.vertices.size(), "vertices");
  if (t.face_image.size() != mesh.faces.size())
    return count_mismatch(t.face_image.size(), "face images", mesh.faces.size(), "faces");
  for (int k : t.face_image) {
    if (k < 0 || k >= int(t.images.size())) return "face image " + std::to_string(k) + " out of range";
  }
  if (t.mime_type != "image/jpeg" && t.mime_type != "image/png")
    return "image type '" + t.mime_type + "' is neither image/jpeg nor image/png";
  return "";
}

// A normal shorter than this has no direction worth keeping.
constexpr double kMinNormalLength = 1e-6;

// Area-weighted sums of the normals of the faces around each vertex.
std::vector<Eigen::Vector3d> face_normal_sums(const DenseMesh& m) {
  std::vector<Eigen::Vector3d> sums(m.vertices.size(), Eigen::Vector3d::Zero());
  for (const auto& f : m.faces) {
    const Eigen::Vector3d n =
        (m.vertices[f[1]] - m.vertices[f[0]]).cross(m.vertices[f[2]] - m.vertices[f[0]]);  // |n| = 2 area
    for (int k : f) sums[k] += n;
  }
  return sums;
}

}  // namespace

std::vector<Eigen::Vector3f> unit_normals(const DenseMesh& mesh) {
  std::vector<Eigen::Vector3d> fallback;
  std::vector<Eigen::Vector3f> out;
  out.reserve(mesh.normals.size());
  for (std::size_t i = 0; i < mesh.normals.size(); ++i) {
    Eigen::Vector3d n = mesh.normals[i].cast<double>();
    if (!n.allFinite() || n.norm() < kMinNormalLength) {
      if (fallback.empty()) fallback = face_normal_sums(mesh);
      n = fallback[i].norm() > 0 ? fallback[i] : Eigen::Vector3d::UnitZ();
    }
    out.push_back(n.normalized().cast<float>());
  }
  return out;
}

std::string mesh_inconsistency(const DenseMesh& mesh, const MeshTexture* texture) {
  const std::size_t n = mesh.vertices.size();
  if (!mesh.colours.empty() && mesh.colours.size() != n) return count_mismatch(mesh.colours.size(), "colours", n, "vertices");
  if (!mesh.normals.empty() && mesh.normals.size() != n) return count_mismatch(mesh.normals.size(), "normals", n, "vertices");
  for (const auto& f : mesh.faces) {
    for (int k : f) {
      if (k < 0 || std::int64_t(k) >= std::int64_t(n))
        return "face index " + std::to_string(k) + " out of range (0.." + std::to_string(std::int64_t(n) - 1) + ")";
    }
  }
  for (const auto& v : mesh.vertices) {
    if (!v.allFinite()) return "a vertex is not finite";
  }
  return texture ? texture_inconsistency(mesh, *texture) : "";
}

}  // namespace strata
