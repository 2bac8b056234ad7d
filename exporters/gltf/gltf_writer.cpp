// exporter.gltf: the GLB container and its JSON (glTF 2.0 specification, sections
// 3.6 buffers/accessors, 3.7 meshes and 4.4 the binary file format).
#include "exporters/gltf/gltf_writer.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/staged_files.hpp"

#include <Eigen/Geometry>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <numbers>

namespace strata {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;  // keys in the order written: asset first, as people read it

static_assert(std::endian::native == std::endian::little, "GLB is little-endian; the writer copies native values");

constexpr const char* kStage = "exporter.gltf";
// Spec constants: accessor component types, bufferView targets, GLB magic and chunk types.
constexpr int kFloat = 5126, kUnsignedInt = 5125;
constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;
constexpr int kTriangles = 4;
constexpr int kLinear = 9729, kLinearMipmapLinear = 9987, kClampToEdge = 33071;  // sampler filters, wrap
constexpr std::uint32_t kGlbMagic = 0x46546C67;  // "glTF"
constexpr std::uint32_t kGlbVersion = 2;
constexpr std::uint32_t kChunkJson = 0x4E4F534A;  // "JSON"
constexpr std::uint32_t kChunkBin = 0x004E4942;   // "BIN\0"
// (E, N, Z) -> glTF (x, y, z) = (E, Z, -N): Y up, and a rotation (determinant +1).
Eigen::Vector3d to_gltf_axes(const Eigen::Vector3d& enz) { return {enz.x(), enz.z(), -enz.y()}; }

std::string mesh_name(const GltfMesh& m, std::size_t i) {
  return m.name.empty() ? fmt::format("mesh {}", i + 1) : m.name;
}

InputError input_error(const fs::path& path, const std::string& what) {
  return InputError(fmt::format("{}: {}: {}", kStage, path.string(), what));
}

void check_meshes(const fs::path& path, std::span<const GltfMesh> meshes) {
  auto fail = [&](const std::string& what) { return input_error(path, what); };
  for (std::size_t i = 0; i < meshes.size(); ++i) {
    const DenseMesh* m = meshes[i].mesh;
    const std::string name = mesh_name(meshes[i], i);
    if (!m || m->faces.empty()) throw fail(fmt::format("mesh '{}' has no faces; glTF export needs a triangle mesh", name));
    const std::string problem = mesh_inconsistency(*m, meshes[i].texture);
    if (!problem.empty()) throw fail(fmt::format("mesh '{}': {}", name, problem));
    if (const auto& c = meshes[i].colour) {
      for (double v : *c)
        if (!(v >= 0 && v <= 1)) throw fail(fmt::format("mesh '{}': colour components must lie in [0, 1]", name));
    }
  }
}

// A rotation matrix is orthonormal with determinant +1, to rounding.
constexpr double kRotationTolerance = 1e-9;

void check_nodes(const fs::path& path, const GltfScene& scene) {
  auto fail = [&](const GltfNode& n, const std::string& what) {
    return input_error(path, fmt::format("node '{}': {}", n.name, what));
  };
  if (scene.nodes.empty()) throw input_error(path, "no node to write");
  for (const auto& n : scene.nodes) {
    if (n.mesh < -1 || n.mesh >= int(scene.meshes.size()))
      throw fail(n, fmt::format("mesh {} out of range ({} meshes)", n.mesh, scene.meshes.size()));
    if (n.position && !n.position->allFinite()) throw fail(n, "position is not finite");
    if (n.rotation) {
      const Eigen::Matrix3d& r = *n.rotation;
      if (!r.allFinite() || (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > kRotationTolerance ||
          r.determinant() < 0)
        throw fail(n, "rotation is not a rotation matrix");
    }
    if (n.camera && !(n.camera->yfov_rad > 0 && n.camera->yfov_rad < std::numbers::pi && n.camera->znear_m > 0 &&
                      n.camera->aspect_ratio >= 0))
      throw fail(n, "camera needs 0 < yfov < pi, znear > 0 and aspect ratio >= 0");
    if (!n.extras_json.empty()) {
      const Json extras = Json::parse(n.extras_json, nullptr, false);
      if (!extras.is_object()) throw fail(n, "extras are not a JSON object");
    }
  }
}

// The local origin of everything placed: mesh vertices and positioned nodes.
Eigen::Vector3d local_origin(const GltfScene& scene, const Eigen::Vector3d& site_origin) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const auto& m : scene.meshes) grow_box(*m.mesh, lo, hi);
  for (const auto& n : scene.nodes) {
    if (n.position) {
      lo = lo.cwiseMin(*n.position);
      hi = hi.cwiseMax(*n.position);
    }
  }
  return model_local_origin(lo, hi, site_origin);
}

// The BIN chunk under construction and the bufferViews that slice it.
class BinaryBuffer {
 public:
  // Appends one bufferView (4-byte aligned: every component written is 4 bytes wide).
  // stride 0: none (index data must not declare one).
  int add_view(const void* data, std::size_t bytes, int target, int stride) {
    while (bytes_.size() % 4 != 0) bytes_.push_back('\0');
    Json v = {{"buffer", 0}, {"byteOffset", bytes_.size()}, {"byteLength", bytes}};
    if (stride > 0) v["byteStride"] = stride;
    if (target > 0) v["target"] = target;  // 0: image data, no vertex or index target
    bytes_.append(static_cast<const char*>(data), bytes);
    views_.push_back(std::move(v));
    return static_cast<int>(views_.size()) - 1;
  }
  const std::string& bytes() const { return bytes_; }
  const Json& views() const { return views_; }

 private:
  std::string bytes_;
  Json views_ = Json::array();
};

int add_accessor(Json& accessors, int view, int component_type, std::size_t count, const char* type) {
  accessors.push_back({{"bufferView", view}, {"componentType", component_type}, {"count", count}, {"type", type}});
  return static_cast<int>(accessors.size()) - 1;
}

// Positions relative to the local origin, in glTF axes, float32; min/max are taken
// from the float values themselves, as the spec requires of POSITION.
int add_positions(BinaryBuffer& bin, Json& accessors, const DenseMesh& m, const Eigen::Vector3d& shift) {
  std::vector<float> xyz;
  xyz.reserve(3 * m.vertices.size());
  std::array<float, 3> lo, hi;
  lo.fill(std::numeric_limits<float>::infinity());
  hi.fill(-std::numeric_limits<float>::infinity());
  for (const auto& v : m.vertices) {
    const Eigen::Vector3d p = to_gltf_axes(v + shift);
    for (int k = 0; k < 3; ++k) {
      const float f = static_cast<float>(p[k]);
      xyz.push_back(f);
      lo[k] = std::min(lo[k], f);
      hi[k] = std::max(hi[k], f);
    }
  }
  const int view = bin.add_view(xyz.data(), xyz.size() * sizeof(float), kArrayBuffer, 12);
  const int a = add_accessor(accessors, view, kFloat, m.vertices.size(), "VEC3");
  accessors[a]["min"] = lo;
  accessors[a]["max"] = hi;
  return a;
}

// Unit normals (geometry/mesh.hpp: an unusable one takes its faces' direction) in glTF axes.
int add_normals(BinaryBuffer& bin, Json& accessors, const DenseMesh& m) {
  std::vector<float> xyz;
  xyz.reserve(3 * m.normals.size());
  for (const Eigen::Vector3f& n : unit_normals(m)) {
    const Eigen::Vector3d g = to_gltf_axes(n.cast<double>());
    for (int k = 0; k < 3; ++k) xyz.push_back(static_cast<float>(g[k]));
  }
  const int view = bin.add_view(xyz.data(), xyz.size() * sizeof(float), kArrayBuffer, 12);
  return add_accessor(accessors, view, kFloat, m.normals.size(), "VEC3");
}

// glTF vertex colours are linear multipliers; the photos' colours are sRGB-encoded
// (IEC 61966-2-1 transfer function). Float keeps the dark tones that 8-bit linear
// values would band.
int add_colours(BinaryBuffer& bin, Json& accessors, const DenseMesh& m) {
  std::array<float, 256> linear;
  for (int c = 0; c < 256; ++c) linear[c] = static_cast<float>(srgb_to_linear(c / 255.0));
  std::vector<float> rgb;
  rgb.reserve(3 * m.colours.size());
  for (const auto& c : m.colours) {
    for (int k = 0; k < 3; ++k) rgb.push_back(linear[c[k]]);
  }
  const int view = bin.add_view(rgb.data(), rgb.size() * sizeof(float), kArrayBuffer, 12);
  return add_accessor(accessors, view, kFloat, m.colours.size(), "VEC3");
}

int add_uvs(BinaryBuffer& bin, Json& accessors, const GltfTexture& t) {
  std::vector<float> uv;
  uv.reserve(2 * t.uv.size());
  for (const auto& p : t.uv) uv.insert(uv.end(), {p.x(), p.y()});
  const int view = bin.add_view(uv.data(), uv.size() * sizeof(float), kArrayBuffer, 8);
  return add_accessor(accessors, view, kFloat, t.uv.size(), "VEC2");
}

// The faces whose image is `image` (all with image -1).
int add_indices(BinaryBuffer& bin, Json& accessors, const DenseMesh& m, const GltfTexture* t = nullptr,
                int image = -1) {
  std::vector<std::uint32_t> idx;
  idx.reserve(3 * m.faces.size());
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    if (image >= 0 && t->face_image[f] != image) continue;
    for (int k : m.faces[f]) idx.push_back(static_cast<std::uint32_t>(k));
  }
  const int view = bin.add_view(idx.data(), idx.size() * sizeof(std::uint32_t), kElementArrayBuffer, 0);
  return add_accessor(accessors, view, kUnsignedInt, idx.size(), "SCALAR");
}

Json asset_json(const ExportFrame& frame, const Eigen::Vector3d& origin) {
  return {{"version", "2.0"},
          {"generator", "strata (exporter.gltf)"},
          {"extras",
           {{"crs", frame.crs},
            {"origin", {origin.x(), origin.y(), origin.z()}},
            {"axes", "x = E, y = Z (up), z = -N; site CRS (E, N, Z) = (t.x + p.x, -(t.z + p.z), t.y + p.y) "
                     "for node translation t and position p"},
            {"units", "metres"}}}};
}

// The surface material every uncoloured mesh shares, then one per flat-coloured mesh.
Json materials_json(const GltfScene& scene, std::vector<int>& material_of_mesh) {
  Json materials = Json::array();
  materials.push_back({{"name", "surface"},
                       {"pbrMetallicRoughness",
                        {{"baseColorFactor", {1.0, 1.0, 1.0, 1.0}}, {"metallicFactor", 0.0}, {"roughnessFactor", 1.0}}},
                       {"doubleSided", true}});
  for (std::size_t i = 0; i < scene.meshes.size(); ++i) {
    const auto& c = scene.meshes[i].colour;
    if (!c) {
      material_of_mesh.push_back(0);
      continue;
    }
    Json m = {{"name", mesh_name(scene.meshes[i], i)},
              {"pbrMetallicRoughness", {{"baseColorFactor", *c}, {"metallicFactor", 0.0}, {"roughnessFactor", 1.0}}}};
    if ((*c)[3] < 1) m["alphaMode"] = "BLEND";  // OPAQUE, the default, would ignore alpha
    m["doubleSided"] = true;
    material_of_mesh.push_back(int(materials.size()));
    materials.push_back(std::move(m));
  }
  return materials;
}

// The embedded images, textures and their materials (one per image) of a textured
// mesh; returns the materials' indices.
std::vector<int> add_texture(const GltfMesh& gm, std::size_t i, BinaryBuffer& bin, Json& images, Json& textures,
                             Json& materials) {
  std::vector<int> out;
  for (std::size_t k = 0; k < gm.texture->images.size(); ++k) {
    const std::string& bytes = gm.texture->images[k];
    const int view = bin.add_view(bytes.data(), bytes.size(), 0, 0);
    images.push_back({{"bufferView", view}, {"mimeType", gm.texture->mime_type}});
    textures.push_back({{"sampler", 0}, {"source", images.size() - 1}});
    materials.push_back({{"name", fmt::format("{} atlas {}", mesh_name(gm, i), k + 1)},
                         {"pbrMetallicRoughness",
                          {{"baseColorTexture", {{"index", textures.size() - 1}}},
                           {"metallicFactor", 0.0},
                           {"roughnessFactor", 1.0}}},
                         {"doubleSided", true}});
    out.push_back(int(materials.size()) - 1);
  }
  return out;
}

// One primitive, or one per atlas image of a textured mesh (materials[k] for image k).
Json mesh_json(const GltfMesh& gm, std::size_t i, const std::vector<int>& materials, const Eigen::Vector3d& shift,
               BinaryBuffer& bin, Json& accessors) {
  const DenseMesh& m = *gm.mesh;
  Json attributes = {{"POSITION", add_positions(bin, accessors, m, shift)}};
  if (!m.normals.empty()) attributes["NORMAL"] = add_normals(bin, accessors, m);
  Json primitives = Json::array();
  if (gm.texture) {
    attributes["TEXCOORD_0"] = add_uvs(bin, accessors, *gm.texture);
    for (std::size_t k = 0; k < materials.size(); ++k) {
      const int indices = add_indices(bin, accessors, m, gm.texture, int(k));
      if (accessors[indices]["count"] == 0) continue;
      primitives.push_back(
          {{"attributes", attributes}, {"indices", indices}, {"material", materials[k]}, {"mode", kTriangles}});
    }
  } else {
    if (!m.colours.empty()) attributes["COLOR_0"] = add_colours(bin, accessors, m);
    const int indices = add_indices(bin, accessors, m);
    primitives.push_back(
        {{"attributes", attributes}, {"indices", indices}, {"material", materials[0]}, {"mode", kTriangles}});
  }
  return {{"name", mesh_name(gm, i)}, {"primitives", primitives}};
}

// (E, N, Z) -> glTF axes as a matrix, for rotations: A R maps the node's axes to glTF's.
Eigen::Matrix3d gltf_axes_matrix() {
  Eigen::Matrix3d a;
  a << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  return a;
}

// Mesh nodes sit at the local origin; positioned nodes at their own site CRS place.
Json node_json(const GltfNode& n, const Eigen::Vector3d& origin, const Eigen::Vector3d& site_origin, Json& cameras) {
  Json j = {{"name", n.name}};
  if (n.mesh >= 0) j["mesh"] = n.mesh;
  if (n.camera) {
    Json perspective = {{"yfov", n.camera->yfov_rad}, {"znear", n.camera->znear_m}};
    if (n.camera->aspect_ratio > 0) perspective["aspectRatio"] = n.camera->aspect_ratio;
    cameras.push_back({{"name", n.name}, {"type", "perspective"}, {"perspective", perspective}});
    j["camera"] = cameras.size() - 1;
  }
  const Eigen::Vector3d t = to_gltf_axes(n.position ? Eigen::Vector3d(site_origin + *n.position) : origin);
  j["translation"] = {t.x(), t.y(), t.z()};
  if (n.rotation) {
    const Eigen::Quaterniond q(gltf_axes_matrix() * *n.rotation);
    j["rotation"] = {q.x(), q.y(), q.z(), q.w()};  // glTF order: x, y, z, w
  }
  if (!n.extras_json.empty()) j["extras"] = Json::parse(n.extras_json);
  return j;
}

// The whole glTF JSON; fills `bin` with the data it refers to.
Json gltf_json(const GltfScene& scene, const ExportFrame& frame, BinaryBuffer& bin) {
  const Eigen::Vector3d origin = local_origin(scene, frame.site_origin);
  const Eigen::Vector3d shift = frame.site_origin - origin;  // site frame -> local, metres
  std::vector<int> material_of_mesh;
  Json materials = materials_json(scene, material_of_mesh);
  Json accessors = Json::array(), gl_meshes = Json::array(), nodes = Json::array(), scene_nodes = Json::array();
  Json cameras = Json::array(), images = Json::array(), textures = Json::array();
  for (std::size_t i = 0; i < scene.meshes.size(); ++i) {
    const GltfMesh& gm = scene.meshes[i];
    const std::vector<int> mesh_materials =
        gm.texture ? add_texture(gm, i, bin, images, textures, materials) : std::vector<int>{material_of_mesh[i]};
    gl_meshes.push_back(mesh_json(gm, i, mesh_materials, shift, bin, accessors));
  }
  for (const auto& n : scene.nodes) {
    nodes.push_back(node_json(n, origin, frame.site_origin, cameras));
    scene_nodes.push_back(nodes.size() - 1);
  }
  Json j = {{"asset", asset_json(frame, origin)},
            {"scene", 0},
            {"scenes", Json::array({Json{{"nodes", scene_nodes}}})},
            {"nodes", nodes}};
  if (!gl_meshes.empty()) j["meshes"] = gl_meshes;
  if (!cameras.empty()) j["cameras"] = cameras;
  j["materials"] = materials;
  if (!textures.empty()) {
    j["samplers"] = Json::array({Json{{"magFilter", kLinear},
                                      {"minFilter", kLinearMipmapLinear},
                                      {"wrapS", kClampToEdge},
                                      {"wrapT", kClampToEdge}}});
    j["images"] = images;
    j["textures"] = textures;
  }
  if (!accessors.empty()) {
    j["accessors"] = accessors;
    j["bufferViews"] = bin.views();
    j["buffers"] = Json::array({Json{{"byteLength", bin.bytes().size()}}});
  }
  return j;
}

void put_u32(std::string& out, std::uint32_t v) {
  char b[4];
  std::memcpy(b, &v, 4);
  out.append(b, 4);
}

// Header (magic, version, total length), then the JSON chunk padded with spaces and
// the BIN chunk padded with zeros, each to 4 bytes.
std::string glb_bytes(const fs::path& path, std::string json, std::string bin) {
  json.append((4 - json.size() % 4) % 4, ' ');
  bin.append((4 - bin.size() % 4) % 4, '\0');
  const std::uint64_t total = 12 + 8 + json.size() + 8 + bin.size();
  if (total > std::numeric_limits<std::uint32_t>::max()) {
    throw InputError(fmt::format("{}: {}: {} bytes, more than one .glb can hold (4 GiB); simplify the mesh", kStage,
                                 path.string(), total));
  }
  std::string out;
  out.reserve(total);
  put_u32(out, kGlbMagic);
  put_u32(out, kGlbVersion);
  put_u32(out, static_cast<std::uint32_t>(total));
  put_u32(out, static_cast<std::uint32_t>(json.size()));
  put_u32(out, kChunkJson);
  out += json;
  put_u32(out, static_cast<std::uint32_t>(bin.size()));
  put_u32(out, kChunkBin);
  out += bin;
  return out;
}

void write_bytes(const fs::path& path, const std::string& bytes) {
  StagedFiles staged(kStage);
  staged.write(path, [&](std::ostream& f) { f.write(bytes.data(), static_cast<std::streamsize>(bytes.size())); });
  fault::point("export.gltf.staged");
  staged.swap_in();
}

}  // namespace

double srgb_to_linear(double s) { return s <= 0.04045 ? s / 12.92 : std::pow((s + 0.055) / 1.055, 2.4); }

GltfNode gltf_camera_node(const std::string& name, const Pose& pose, const Intrinsics& intrinsics) {
  GltfNode n;
  n.name = name;
  n.position = pose.centre();
  // glTF camera axes -> OpenCV camera axes (flip y and z), then camera -> site (R^T).
  const Eigen::Matrix3d flip = Eigen::Vector3d(1, -1, -1).asDiagonal();
  n.rotation = pose.R.transpose() * flip;
  GltfCamera c;
  if (intrinsics.height > 0 && intrinsics.fy > 0) c.yfov_rad = 2 * std::atan(0.5 * intrinsics.height / intrinsics.fy);
  if (intrinsics.height > 0) c.aspect_ratio = double(intrinsics.width) / intrinsics.height;
  if (c.yfov_rad > 0) n.camera = c;
  return n;
}

void write_glb(const fs::path& path, std::span<const GltfMesh> meshes, const ExportFrame& frame) {
  if (meshes.empty()) throw input_error(path, "no mesh to write");
  GltfScene scene;
  scene.meshes.assign(meshes.begin(), meshes.end());
  for (std::size_t i = 0; i < meshes.size(); ++i) {
    GltfNode n;
    n.name = mesh_name(meshes[i], i);
    n.mesh = int(i);
    scene.nodes.push_back(std::move(n));
  }
  write_glb(path, scene, frame);
}

std::string encode_glb(const GltfScene& scene, const ExportFrame& frame, const fs::path& name) {
  check_meshes(name, scene.meshes);
  check_nodes(name, scene);
  BinaryBuffer bin;
  const Json json = gltf_json(scene, frame, bin);
  return glb_bytes(name, json.dump(), bin.bytes());
}

void write_glb(const fs::path& path, const GltfScene& scene, const ExportFrame& frame) {
  write_bytes(path, encode_glb(scene, frame, path));
}

}  // namespace strata
