#pragma once
// The site model as a glTF scene: what `export model` writes, `export viewer` embeds and
// the field station's 3D page shows, built once here so they cannot drift apart.
#include "exporters/gltf/gltf_writer.hpp"
#include "geometry/mesh.hpp"
#include "importers/mesh/ply_mesh.hpp"
#include "products/texture_atlas.hpp"
#include "project/project.hpp"
#include "project/records.hpp"

#include <cstddef>
#include <deque>
#include <filesystem>
#include <string>

namespace strata {

// How layer meshes are textured from their photos (products.texture) in a model or viewer.
struct ModelTextureArgs {
  int jpeg_quality = 90;     // atlas JPEG quality, [1, 100]; 0: PNG
  int atlas_size_px = 4096;  // side of a square atlas, texels
  bool colour_gains = true;  // per-photo colour gains fitted over the faces several photos see
};

// A layer mesh textured from its photos, as the model writers take it.
struct TexturedModel {
  TexturedMesh textured;  // the mesh, its UVs and the atlases as pixels (for --check-photos)
  MeshTexture texture;    // the same UVs with the atlases encoded
};

// Logs the texture's summary, naming `layer`. Throws as build_texture_atlas.
TexturedModel texture_layer_mesh(const std::vector<OrthoView>& views, const DenseMesh& mesh, const ModelTextureArgs& t,
                                 const std::string& layer);

// The scene and the meshes and textures it points to (deques: adding one must not move the others).
struct SiteScene {
  std::deque<DenseMesh> meshes;
  std::deque<MeshTexture> textures;
  GltfScene scene;
  std::size_t layers = 0, units = 0, markers = 0, finds = 0, cameras = 0;  // nodes of each kind
  std::size_t textured_layers = 0;

  void add_mesh(std::string name, DenseMesh mesh, std::optional<std::array<double, 4>> colour,
                std::string extras_json = "", std::optional<MeshTexture> texture = std::nullopt);
};

struct SiteSceneOptions {
  // Level of detail of every layer mesh (layer_mesh_at_level), >= 0; 0: the fused mesh.
  int lod = 0;
  // Faces per layer mesh; larger meshes are simplified (CGAL edge collapse, colours and
  // normals carried). 0: keep every face.
  std::size_t max_layer_faces = 0;
  // Set: every layer with an aligned photo set is textured from its photos (the others,
  // e.g. a layer recorded by range scans alone, keep their vertex colours).
  std::optional<ModelTextureArgs> texture;
  std::string only_layer;  // "": every layer and the unit solids; else this layer alone (no unit solids)
  std::string command = "export model";  // names the command in warnings and errors
};

// Layer meshes (top first), unit solids, markers, finds, cameras of the project in `dir`.
// Unit solids are simplified like the layers: to faces / 4^lod and to max_layer_faces.
// Finds are nodes "find ID" at their point with extras {find, recorded_unit, type,
// description, site_crs: [E, N, Z]} and, when the voxel model exists, geometric_unit,
// distance_m and conflict (as `strata finds --json`).
// Throws InputError when no layer has a dense mesh yet.
SiteScene build_site_scene(Project& p, const std::string& dir, const SiteSceneOptions& options);

// The file of a product the dense stage recorded, refused (IoError) when it has gone or
// changed since.
std::filesystem::path checked_product_file(Project& p, const LayerRecord& l, const ProductRecord& product,
                                           const std::string& dir);

// A dense-stage PLY's mesh in the site frame (relative to the site origin).
DenseMesh site_frame_mesh(PlyContents ply, const Eigen::Vector3d& site_origin);

// Fewest faces a level of detail may leave: below this a layer is a handful of
// triangles, no longer a model of its surface.
constexpr std::size_t kMinLevelOfDetailFaces = 100;

// Refuses (InputError naming the value) a negative level of detail.
void check_level_of_detail(int lod);

// Level of detail `lod` of a layer's mesh: 0 the mesh itself, N >= 1 simplified to
// faces / 4^N (simplify_mesh: edge collapse, colours and normals carried), each level
// a quarter of the one above, as a halving of the edge length would give. Refuses
// (InputError naming the value and the layer) a level that would leave fewer than
// kMinLevelOfDetailFaces faces. Logs the face count of the level.
DenseMesh layer_mesh_at_level(DenseMesh mesh, int lod, const std::string& layer, const std::string& command);

}  // namespace strata
