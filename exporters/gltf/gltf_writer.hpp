#pragma once
// exporter.gltf: triangle meshes as one glTF 2.0 binary (.glb), vertex-coloured or
// textured (an atlas of embedded JPEG/PNG images).
//
// Frame. glTF stores float32 positions and is Y-up, metres. Site CRS coordinates at
// UTM magnitudes (E 734000, N 4174000) would lose about 0.5 m in float32, so the
// positions are relative to a local origin: the centre of the bounding box of all the
// meshes in the file, in site CRS coordinates, rounded to whole metres (exact in
// float32 too). Every mesh node's `translation` is that origin, and the axes are mapped
//   glTF x = E, glTF y = Z (up), glTF z = -N
// (a rotation, so counter-clockwise faces stay counter-clockwise). A site CRS point is
// therefore (E, N, Z) = (t.x + p.x, -(t.z + p.z), t.y + p.y) for node translation t
// and position p. asset.extras records {"crs", "origin": [E, N, Z], "axes", "units"}.
//
// Per mesh: POSITION (float VEC3, min/max), NORMAL (float VEC3, unit length) when the
// mesh has normals, COLOR_0 (float VEC3, linear: glTF vertex colours are linear, the
// photos' colours sRGB) when it has colours, indices UNSIGNED_INT, one shared material
// (pbrMetallicRoughness: white, metallic 0, roughness 1, double-sided: an excavated
// surface is seen from below in sections). A mesh with a flat colour gets a material
// of its own instead (baseColorFactor, alphaMode BLEND when its alpha is below 1).
//
// A scene (GltfScene) adds nodes without meshes: markers and cameras, placed at
// `translation` = their own position (origin + local, in the JSON's double precision),
// and glTF perspective cameras. The local origin then covers their positions too.
#include "geometry/mesh.hpp"
#include "geometry/camera.hpp"

#include <Eigen/Core>

#include <array>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace strata {

// A texture atlas for one mesh (geometry/mesh.hpp): the images are embedded
// (bufferView + mimeType), one material per image (baseColorTexture; the images are
// sRGB as glTF expects), one primitive per image holding the faces that use it; UVs
// go to TEXCOORD_0.
using GltfTexture = MeshTexture;

struct GltfMesh {
  std::string name;                // node and mesh name (e.g. the layer); "" -> "mesh N"
  const DenseMesh* mesh = nullptr; // not owned; vertices in the site frame, at least one face
  // Linear RGBA in [0, 1], one colour for the whole mesh (vertex colours, if any, still
  // multiply it); none: the shared white material.
  std::optional<std::array<double, 4>> colour = std::nullopt;
  // Not owned; set: the mesh is textured (vertex colours and `colour` are then not written).
  const GltfTexture* texture = nullptr;
};

// glTF perspective camera: looks along its node's -z, +y up the image.
struct GltfCamera {
  double yfov_rad = 0;      // vertical field of view, radians, in (0, pi)
  double aspect_ratio = 0;  // width / height; 0: left to the viewer
  double znear_m = 0.01;    // metres
};

struct GltfNode {
  std::string name;
  int mesh = -1;  // index into GltfScene::meshes; -1: none
  // metres, site frame; none: the local origin (a mesh's vertices carry its place)
  std::optional<Eigen::Vector3d> position = std::nullopt;
  // Rotation from the node's own axes to the site axes (E, N, Z); none: identity.
  std::optional<Eigen::Matrix3d> rotation = std::nullopt;
  std::string extras_json = "";  // a JSON object for the node's `extras`; "": none
  std::optional<GltfCamera> camera = std::nullopt;
};

struct GltfScene {
  std::vector<GltfMesh> meshes;
  std::vector<GltfNode> nodes;  // in this order in the file and the scene
};

// An sRGB-encoded component in [0, 1] as the linear value glTF colours are
// (IEC 61966-2-1 transfer function).
double srgb_to_linear(double srgb);

// A node at the camera centre of `pose` (site frame) whose rotation and glTF camera
// show what the photo shows: OpenCV camera axes (x right, y down, z forward) become
// glTF's (x right, y up, looking along -z); yfov = 2 atan(height / 2 fy).
GltfNode gltf_camera_node(const std::string& name, const Pose& pose, const Intrinsics& intrinsics);

// Writes `meshes` to `path` (a staged name beside it, renamed when complete).
// frame.site_origin and frame.crs give the site CRS; frame.crs_coordinates is ignored
// (glTF always gets the local origin above). Throws InputError for a mesh without
// faces or with inconsistent arrays, IoError("exporter.gltf: <path>: ...") when the
// file cannot be written.
// One node per mesh, in order.
void write_glb(const std::filesystem::path& path, std::span<const GltfMesh> meshes, const ExportFrame& frame);

// The scene's nodes in order. Also InputError for a node naming a missing mesh, a
// rotation that is not one, an invalid colour or camera, or extras that are not a
// JSON object; meshes no node uses are still written.
void write_glb(const std::filesystem::path& path, const GltfScene& scene, const ExportFrame& frame);

// The same file's bytes, for a caller that embeds them (the viewer page); `name`
// stands for the file in error messages.
std::string encode_glb(const GltfScene& scene, const ExportFrame& frame, const std::filesystem::path& name);

}  // namespace strata
