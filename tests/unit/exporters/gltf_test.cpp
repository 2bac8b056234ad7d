// exporter.gltf: the written .glb parsed byte by byte here (no glTF library), its
// container and JSON checked against the glTF 2.0 rules a viewer relies on, and the
// coordinates of a mesh at UTM magnitudes recovered from node translation + float
// positions.
#include "core/error.hpp"
#include "exporters/gltf/gltf_writer.hpp"
#include "support/test_support.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>

namespace strata {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// metres: what the local origin must preserve (a tenth of the millimetre the survey
// resolves), against the ~0.25-0.5 m float32 spacing at N 4174000.
constexpr double kSubMillimetre = 1e-4;
// float32 normal components after normalising in double: a few ulps.
constexpr double kUnitTolerance = 1e-6;
// float32 of a linear colour value in [0, 1].
constexpr double kColourTolerance = 1e-6;
// radians / metres / unit quaternion norm: double arithmetic on exact inputs.
constexpr double kExact = 1e-9;
const Eigen::Vector3d kSiteOrigin(733900.0, 4173900.0, 1450.0);  // E, N, Z: rounded like Project's

// ---- a reader for the GLB container, independent of the writer ----------------------

struct Glb {
  json gltf;
  std::string bin;  // the BIN chunk's bytes, padding included
};

std::uint32_t u32_at(const std::string& b, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}

// Throws std::runtime_error naming the first rule of the container that is broken.
Glb parse_glb(const std::string& b) {
  auto need = [](bool ok, const std::string& what) {
    if (!ok) throw std::runtime_error(what);
  };
  need(b.size() >= 12 + 8, "shorter than a header and one chunk header");
  need(u32_at(b, 0) == 0x46546C67, "magic is not glTF");
  need(u32_at(b, 4) == 2, "version is not 2");
  need(u32_at(b, 8) == b.size(), "header length differs from the file size");
  const std::uint32_t json_len = u32_at(b, 12);
  need(u32_at(b, 16) == 0x4E4F534A, "first chunk is not JSON");
  need(json_len % 4 == 0, "JSON chunk length not a multiple of 4");
  const std::size_t bin_header = 20 + std::size_t{json_len};
  need(bin_header + 8 <= b.size(), "no room for the BIN chunk header");
  const std::string json_text = b.substr(20, json_len);
  const std::size_t close = json_text.find_last_of('}');
  need(close != std::string::npos && json_text.find_first_not_of(' ', close + 1) == std::string::npos,
       "JSON chunk not padded with spaces");
  const std::uint32_t bin_len = u32_at(b, bin_header);
  need(u32_at(b, bin_header + 4) == 0x004E4942, "second chunk is not BIN");
  need(bin_len % 4 == 0, "BIN chunk length not a multiple of 4");
  need(bin_header + 8 + bin_len == b.size(), "chunks do not end at the end of the file");
  Glb g;
  g.gltf = json::parse(json_text);  // throws on malformed JSON
  g.bin = b.substr(bin_header + 8, bin_len);
  return g;
}

std::size_t component_bytes(int type) {
  switch (type) {
    case 5120: case 5121: return 1;
    case 5122: case 5123: return 2;
    case 5125: case 5126: return 4;
    default: return 0;
  }
}

std::size_t components(const std::string& type) {
  if (type == "SCALAR") return 1;
  if (type == "VEC2") return 2;
  if (type == "VEC3") return 3;
  if (type == "VEC4") return 4;
  return 0;
}

// Every view inside the buffer, every accessor inside its view: the rules the
// glTF-Validator checks first, as a list of what is broken ("" when nothing).
std::string layout_problems(const Glb& g) {
  std::string p;
  const json& buffers = g.gltf.at("buffers");
  if (buffers.size() != 1 || buffers[0].contains("uri")) p += "not one embedded buffer; ";
  const std::size_t buffer_len = buffers[0].at("byteLength");
  if (buffer_len > g.bin.size() || g.bin.size() - buffer_len > 3) p += "buffer length vs BIN chunk; ";
  const json& views = g.gltf.at("bufferViews");
  for (const auto& v : views) {
    const std::size_t off = v.value("byteOffset", 0), len = v.at("byteLength");
    if (v.at("buffer") != 0 || off % 4 != 0 || off + len > buffer_len) p += "view outside buffer/unaligned; ";
    if (!v.contains("target")) {  // image data: no stride, and an image must use it
      if (v.contains("byteStride")) p += "image view stride; ";
      continue;
    }
    const int target = v.at("target");
    if (target != 34962 && target != 34963) p += "view target; ";
    if (v.contains("byteStride") && (target == 34963 || int(v["byteStride"]) % 4 != 0)) p += "view stride; ";
  }
  for (const auto& im : g.gltf.value("images", json::array())) {
    const std::size_t view = im.at("bufferView");
    if (view >= views.size() || views[view].contains("target")) p += "image view; ";
  }
  for (std::size_t i = 0; i < views.size(); ++i) {
    bool used = false;
    for (const auto& a : g.gltf.at("accessors")) used |= std::size_t(a.at("bufferView")) == i;
    for (const auto& im : g.gltf.value("images", json::array())) used |= std::size_t(im.at("bufferView")) == i;
    if (!used) p += "unused view; ";
  }
  for (const auto& a : g.gltf.at("accessors")) {
    const std::size_t view = a.at("bufferView");
    if (view >= views.size()) {
      p += "accessor view missing; ";
      continue;
    }
    const std::size_t elem = component_bytes(a.at("componentType")) * components(a.at("type"));
    const std::size_t stride = views[view].value("byteStride", elem), count = a.at("count");
    const std::size_t off = a.value("byteOffset", 0);
    if (elem == 0 || count == 0) p += "accessor type/count; ";
    else if (off + stride * (count - 1) + elem > std::size_t(views[view].at("byteLength"))) p += "accessor overflows view; ";
  }
  return p;
}

template <typename T>
std::vector<T> accessor_data(const Glb& g, int index) {
  const json& a = g.gltf.at("accessors").at(index);
  const json& v = g.gltf.at("bufferViews").at(int(a.at("bufferView")));
  const std::size_t n = components(a.at("type")), count = a.at("count");
  const std::size_t stride = v.value("byteStride", n * sizeof(T));
  const std::size_t start = std::size_t(v.value("byteOffset", 0)) + std::size_t(a.value("byteOffset", 0));
  std::vector<T> out(n * count);
  for (std::size_t i = 0; i < count; ++i) std::memcpy(&out[i * n], g.bin.data() + start + i * stride, n * sizeof(T));
  return out;
}

Glb read_glb(const fs::path& p) { return parse_glb(test::read_text(p)); }

// ---- meshes with known answers -------------------------------------------------------

// A 4 x 3 grid over E 733998.7 .. 734001.7, N 4173998.9 .. 4174001.5, Z 1449.6 .. 1450.3
// (box centre 734000.2, 4174000.2, 1449.95: local origin 734000, 4174000, 1450), with
// tenth-of-millimetre digits everywhere; faces counter-clockwise seen from above.
DenseMesh utm_grid() {
  DenseMesh m;
  const double e0 = 98.7, n0 = 98.9;  // site frame, metres
  for (int j = 0; j < 3; ++j) {
    for (int i = 0; i < 4; ++i) {
      const double z = -0.4 + 0.7 * (i + j) / 5.0 + 0.00013 * i;
      m.vertices.emplace_back(e0 + i + 0.00017 * j, n0 + 1.3 * j + 0.00011 * i, z);
    }
  }
  m.vertices[0].z() = -0.4;  // the box's low corner stays exact
  m.vertices[11].z() = 0.3;
  for (int j = 0; j < 2; ++j) {
    for (int i = 0; i < 3; ++i) {
      const int a = j * 4 + i;
      m.faces.push_back({a, a + 1, a + 5});
      m.faces.push_back({a, a + 5, a + 4});
    }
  }
  return m;
}

ExportFrame utm_frame() {
  ExportFrame f;
  f.site_origin = kSiteOrigin;
  f.crs = "EPSG:32636";
  return f;
}

void write_one(const fs::path& p, const DenseMesh& m, const std::string& name = "L101") {
  const GltfMesh meshes[] = {{name, &m}};
  write_glb(p, meshes, utm_frame());
}

TEST(GltfExport, ContainerAndAccessorsFollowTheSpec) {
  test::ScratchDir dir("gltf_container");
  DenseMesh a = utm_grid(), b = utm_grid();
  a.colours.assign(a.vertices.size(), Rgb8(200, 150, 100));
  a.normals.assign(a.vertices.size(), Eigen::Vector3f::UnitZ());
  for (auto& v : b.vertices) v.z() -= 0.25;  // the layer below
  const GltfMesh meshes[] = {{"L101", &a}, {"L102", &b}};
  write_glb(dir / "site.glb", meshes, utm_frame());
  EXPECT_FALSE(fs::exists(dir / "site.next.glb"));

  const Glb g = read_glb(dir / "site.glb");
  EXPECT_EQ(layout_problems(g), "");
  const json& j = g.gltf;
  EXPECT_EQ(j["asset"]["version"], "2.0");
  ASSERT_EQ(j["nodes"].size(), 2u);
  EXPECT_EQ(j["nodes"][0]["name"], "L101");
  EXPECT_EQ(j["nodes"][1]["name"], "L102");
  EXPECT_EQ(j["scenes"][int(j["scene"])]["nodes"], json({0, 1}));
  ASSERT_EQ(j["materials"].size(), 1u);
  EXPECT_EQ(j["materials"][0]["pbrMetallicRoughness"]["metallicFactor"], 0.0);
  EXPECT_EQ(j["materials"][0]["pbrMetallicRoughness"]["roughnessFactor"], 1.0);
  EXPECT_EQ(j["materials"][0]["doubleSided"], true);
  for (const auto& node : j["nodes"]) {
    const json& prim = j["meshes"][int(node["mesh"])]["primitives"][0];
    EXPECT_EQ(prim["mode"], 4);
    EXPECT_EQ(prim["material"], 0);
    const json& pos = j["accessors"][int(prim["attributes"]["POSITION"])];
    EXPECT_EQ(pos["componentType"], 5126);
    EXPECT_EQ(pos["type"], "VEC3");
    const std::size_t n_vertices = pos["count"];
    for (const auto& [name, acc] : prim["attributes"].items()) EXPECT_EQ(j["accessors"][int(acc)]["count"], n_vertices) << name;
    // min/max exactly those of the float data.
    const auto xyz = accessor_data<float>(g, prim["attributes"]["POSITION"]);
    for (int k = 0; k < 3; ++k) {
      float lo = xyz[k], hi = xyz[k];
      for (std::size_t i = k; i < xyz.size(); i += 3) lo = std::min(lo, xyz[i]), hi = std::max(hi, xyz[i]);
      EXPECT_EQ(float(pos["min"][k]), lo) << k;
      EXPECT_EQ(float(pos["max"][k]), hi) << k;
    }
    const json& idx = j["accessors"][int(prim["indices"])];
    EXPECT_EQ(idx["componentType"], 5125);
    EXPECT_EQ(j["bufferViews"][int(idx["bufferView"])]["target"], 34963);
    EXPECT_EQ(j["bufferViews"][int(pos["bufferView"])]["target"], 34962);
    for (std::uint32_t i : accessor_data<std::uint32_t>(g, prim["indices"])) EXPECT_LT(i, n_vertices);
  }
  EXPECT_TRUE(j["meshes"][0]["primitives"][0]["attributes"].contains("NORMAL"));
  EXPECT_TRUE(j["meshes"][0]["primitives"][0]["attributes"].contains("COLOR_0"));
  EXPECT_FALSE(j["meshes"][1]["primitives"][0]["attributes"].contains("NORMAL"));
  EXPECT_FALSE(j["meshes"][1]["primitives"][0]["attributes"].contains("COLOR_0"));
}

TEST(GltfExport, UtmCoordinatesSurviveToATenthOfAMillimetre) {
  test::ScratchDir dir("gltf_utm");
  const DenseMesh m = utm_grid();
  // The test can fail: float32 alone would be ~0.25 m off here.
  const double e = m.vertices[5].x() + kSiteOrigin.x(), n = m.vertices[5].y() + kSiteOrigin.y();
  ASSERT_GT(std::abs(double(float(n)) - n) + std::abs(double(float(e)) - e), 100 * kSubMillimetre);
  write_one(dir / "l.glb", m);
  const Glb g = read_glb(dir / "l.glb");
  const json& extras = g.gltf["asset"]["extras"];
  EXPECT_EQ(extras["crs"], "EPSG:32636");
  EXPECT_EQ(extras["origin"], json({734000.0, 4174000.0, 1450.0}));
  EXPECT_NE(std::string(extras["axes"]).find("y = Z (up)"), std::string::npos);
  const json& node = g.gltf["nodes"][0];
  EXPECT_EQ(node["translation"], json({734000.0, 1450.0, -4174000.0}));  // (E, Z, -N)
  const double tx = node["translation"][0], ty = node["translation"][1], tz = node["translation"][2];
  const auto p = accessor_data<float>(g, g.gltf["meshes"][0]["primitives"][0]["attributes"]["POSITION"]);
  ASSERT_EQ(p.size(), 3 * m.vertices.size());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    const Eigen::Vector3d truth = m.vertices[i] + kSiteOrigin;
    const Eigen::Vector3d back(tx + p[3 * i], -(tz + p[3 * i + 2]), ty + p[3 * i + 1]);
    EXPECT_LT((back - truth).cwiseAbs().maxCoeff(), kSubMillimetre) << i;
  }
  // Counter-clockwise from above stays counter-clockwise seen from +y (up).
  const auto idx = accessor_data<std::uint32_t>(g, g.gltf["meshes"][0]["primitives"][0]["indices"]);
  auto at = [&](std::uint32_t k) { return Eigen::Vector3d(p[3 * k], p[3 * k + 1], p[3 * k + 2]); };
  for (std::size_t f = 0; f < idx.size(); f += 3) {
    EXPECT_GT((at(idx[f + 1]) - at(idx[f])).cross(at(idx[f + 2]) - at(idx[f])).y(), 0.0) << f / 3;
  }
}

TEST(GltfExport, NormalsAreUnitInGltfAxesAndColoursLinear) {
  test::ScratchDir dir("gltf_attr");
  DenseMesh m = utm_grid();
  m.normals.assign(m.vertices.size(), Eigen::Vector3f(0, 0, 2));  // not unit: normalised
  m.normals[1] = Eigen::Vector3f(0, 3, 4);                        // N and Z -> (0, 0.8, -0.6)
  m.normals[2] = Eigen::Vector3f::Zero();                         // none: its faces' direction
  m.colours.assign(m.vertices.size(), Rgb8(255, 0, 128));
  m.colours[3] = Rgb8(10, 10, 10);  // the linear branch of the sRGB curve
  write_one(dir / "l.glb", m);
  const Glb g = read_glb(dir / "l.glb");
  const json& attr = g.gltf["meshes"][0]["primitives"][0]["attributes"];
  const auto n = accessor_data<float>(g, attr["NORMAL"]);
  EXPECT_NEAR(n[0], 0.0, kUnitTolerance);
  EXPECT_NEAR(n[1], 1.0, kUnitTolerance);
  EXPECT_NEAR(n[2], 0.0, kUnitTolerance);
  EXPECT_NEAR(n[3], 0.0, kUnitTolerance);
  EXPECT_NEAR(n[4], 0.8, kUnitTolerance);
  EXPECT_NEAR(n[5], -0.6, kUnitTolerance);
  const Eigen::Vector3d from_faces(n[6], n[7], n[8]);
  EXPECT_NEAR(from_faces.norm(), 1.0, kUnitTolerance);
  EXPECT_GT(from_faces.y(), 0.9);  // the grid faces up, tilted ~10 degrees
  EXPECT_EQ(g.gltf["accessors"][int(attr["COLOR_0"])]["componentType"], 5126);
  EXPECT_EQ(g.gltf["accessors"][int(attr["COLOR_0"])]["type"], "VEC3");
  const auto c = accessor_data<float>(g, attr["COLOR_0"]);
  EXPECT_NEAR(c[0], 1.0, kColourTolerance);
  EXPECT_NEAR(c[1], 0.0, kColourTolerance);
  EXPECT_NEAR(c[2], std::pow((128 / 255.0 + 0.055) / 1.055, 2.4), kColourTolerance);  // 0.2158605
  EXPECT_NEAR(c[9], 10 / 255.0 / 12.92, kColourTolerance);
}

TEST(GltfExport, TexturedMeshEmbedsItsAtlasesWithUvsAndOnePrimitivePerAtlas) {
  test::ScratchDir dir("gltf_texture");
  const DenseMesh m = utm_grid();
  GltfTexture tex;
  for (std::size_t i = 0; i < m.vertices.size(); ++i) tex.uv.emplace_back(0.1f * float(i % 4), 0.2f * float(i / 4));
  for (std::size_t f = 0; f < m.faces.size(); ++f) tex.face_image.push_back(f < 4 ? 0 : 1);
  const std::string png1 = "\x89PNG\r\n\x1a\nfirst", png2 = "\x89PNG\r\n\x1a\nsecond image";
  tex.images = {png1, png2};
  tex.mime_type = "image/png";
  GltfMesh gm{"L101", &m};
  gm.texture = &tex;
  write_glb(dir / "t.glb", std::span<const GltfMesh>(&gm, 1), utm_frame());
  const Glb g = read_glb(dir / "t.glb");
  EXPECT_EQ(layout_problems(g), "");
  const json& j = g.gltf;
  ASSERT_EQ(j.at("images").size(), 2u);
  ASSERT_EQ(j.at("textures").size(), 2u);
  ASSERT_EQ(j.at("samplers").size(), 1u);
  for (int k = 0; k < 2; ++k) {
    const json& im = j["images"][k];
    EXPECT_EQ(im.at("mimeType"), "image/png");
    const json& v = j["bufferViews"][int(im.at("bufferView"))];
    EXPECT_FALSE(v.contains("target"));  // image data is neither vertices nor indices
    const std::string bytes = g.bin.substr(v.at("byteOffset"), v.at("byteLength"));
    EXPECT_EQ(bytes, k == 0 ? png1 : png2);
  }
  const json& prims = j["meshes"][0]["primitives"];
  ASSERT_EQ(prims.size(), 2u);
  std::size_t indices = 0;
  for (int k = 0; k < 2; ++k) {
    const json& mat = j["materials"][int(prims[k].at("material"))];
    EXPECT_EQ(int(j["textures"][int(mat["pbrMetallicRoughness"]["baseColorTexture"]["index"])]["source"]), k);
    EXPECT_FALSE(prims[k]["attributes"].contains("COLOR_0"));
    const int uv = prims[k]["attributes"].at("TEXCOORD_0");
    EXPECT_EQ(j["accessors"][uv]["type"], "VEC2");
    const auto data = accessor_data<float>(g, uv);
    ASSERT_EQ(data.size(), 2 * m.vertices.size());
    EXPECT_FLOAT_EQ(data[2 * 5], 0.1f);
    EXPECT_FLOAT_EQ(data[2 * 5 + 1], 0.2f);
    indices += std::size_t(j["accessors"][int(prims[k]["indices"])]["count"]);
  }
  EXPECT_EQ(indices, 3 * m.faces.size());
  gm.texture = nullptr;
  tex.uv.pop_back();
  gm.texture = &tex;
  EXPECT_THROW(write_glb(dir / "bad.glb", std::span<const GltfMesh>(&gm, 1), utm_frame()), InputError);
}

TEST(GltfExport, MeshWithoutFacesIsRefusedNamingFileAndMesh) {
  test::ScratchDir dir("gltf_nofaces");
  DenseMesh m = utm_grid();
  m.faces.clear();
  try {
    write_one(dir / "l.glb", m, "L7");
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("exporter.gltf"), std::string::npos) << what;
    EXPECT_NE(what.find((dir / "l.glb").string()), std::string::npos) << what;
    EXPECT_NE(what.find("'L7' has no faces"), std::string::npos) << what;
  }
  EXPECT_FALSE(fs::exists(dir / "l.glb"));
  EXPECT_THROW(write_glb(dir / "l.glb", std::span<const GltfMesh>{}, utm_frame()), InputError);
}

TEST(GltfExport, UnwritablePathIsAnIoErrorNamingTheFile) {
  test::ScratchDir dir("gltf_unwritable");
  test::write_text(dir / "plain_file", "a file, not a folder");
  const fs::path out = dir / "plain_file" / "l.glb";  // refused even to root
  try {
    write_one(out, utm_grid());
    FAIL() << "no error";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find(out.string()), std::string::npos) << e.what();
  }
  fs::create_directories(dir / "l.glb");  // a folder where the file should go
  EXPECT_THROW(write_one(dir / "l.glb", utm_grid()), IoError);
  EXPECT_FALSE(fs::exists(dir / "l.next.glb"));
}

// ---- a scene: meshes, a mesh-less node with extras, a camera ------------------------

// A mesh-less node's translation back in site CRS (E, N, Z).
Eigen::Vector3d site_crs_of(const json& node) {
  const json& t = node.at("translation");
  return {t[0].get<double>(), -t[2].get<double>(), t[1].get<double>()};
}

TEST(GltfExport, SceneKeepsNodeOrderExtrasMaterialsAndCameras) {
  test::ScratchDir dir("gltf_scene");
  DenseMesh layer = utm_grid(), solid = utm_grid();
  for (auto& v : solid.vertices) v.z() -= 0.25;
  GltfScene scene;
  scene.meshes.push_back({"layer L1", &layer});
  scene.meshes.push_back({"unit 101", &solid, std::array<double, 4>{0.2, 0.4, 0.6, 0.5}});
  GltfNode l1{.name = "layer L1", .mesh = 0};
  GltfNode u101{.name = "unit 101", .mesh = 1};
  u101.extras_json = R"({"unit": "101", "volume_m3": 1.25, "interval_m3": [1.2, 1.3]})";
  GltfNode gcp{.name = "marker GCP1", .position = Eigen::Vector3d(100.1234, 100.5678, 0.1)};
  gcp.extras_json = R"({"kind": "control"})";
  // Straight down from 2 m above the ground, north up in the image; a 6000 x 4000 photo.
  const Pose down = Pose::look_at({100, 100, 2}, {100, 100, 0}, Eigen::Vector3d::UnitY());
  const Intrinsics lens{6000, 4000, 5000, 5000, 2999.5, 1999.5};
  scene.nodes = {l1, u101, gcp, gltf_camera_node("camera L1/IMG_0001.jpg", down, lens)};
  write_glb(dir / "site.glb", scene, utm_frame());

  const Glb g = read_glb(dir / "site.glb");
  EXPECT_EQ(layout_problems(g), "");
  const json& j = g.gltf;
  ASSERT_EQ(j["nodes"].size(), 4u);
  const char* names[] = {"layer L1", "unit 101", "marker GCP1", "camera L1/IMG_0001.jpg"};
  for (int i = 0; i < 4; ++i) EXPECT_EQ(j["nodes"][i]["name"], names[i]) << i;
  EXPECT_EQ(j["scenes"][int(j["scene"])]["nodes"], json({0, 1, 2, 3}));
  // The origin covers the camera 2 m up: Z from -0.65 to 2, centre 1450.675 -> 1451.
  EXPECT_EQ(j["asset"]["extras"]["origin"], json({734000.0, 4174000.0, 1451.0}));
  EXPECT_EQ(j["nodes"][0]["translation"], json({734000.0, 1451.0, -4174000.0}));

  EXPECT_EQ(j["nodes"][1]["extras"], json::parse(u101.extras_json));
  EXPECT_FALSE(j["nodes"][0].contains("extras"));
  const json& marker = j["nodes"][2];
  EXPECT_FALSE(marker.contains("mesh"));
  EXPECT_EQ(marker["extras"]["kind"], "control");
  EXPECT_LT((site_crs_of(marker) - (kSiteOrigin + *gcp.position)).cwiseAbs().maxCoeff(), kSubMillimetre);

  // Materials: the shared white surface, then the unit's own translucent colour.
  const json& mats = j["materials"];
  EXPECT_EQ(j["meshes"][0]["primitives"][0]["material"], 0);
  const json& unit_mat = mats[int(j["meshes"][1]["primitives"][0]["material"])];
  EXPECT_EQ(unit_mat["pbrMetallicRoughness"]["baseColorFactor"], json({0.2, 0.4, 0.6, 0.5}));
  EXPECT_EQ(unit_mat["alphaMode"], "BLEND");
  EXPECT_FALSE(mats[0].contains("alphaMode"));

  const json& cam_node = j["nodes"][3];
  const json& cam = j["cameras"][int(cam_node["camera"])];
  EXPECT_EQ(cam["type"], "perspective");
  EXPECT_NEAR(double(cam["perspective"]["yfov"]), 2 * std::atan(2000.0 / 5000.0), kExact);
  EXPECT_NEAR(double(cam["perspective"]["aspectRatio"]), 1.5, kExact);
  EXPECT_GT(double(cam["perspective"]["znear"]), 0.0);
  EXPECT_LT((site_crs_of(cam_node) - (kSiteOrigin + Eigen::Vector3d(100, 100, 2))).cwiseAbs().maxCoeff(), kSubMillimetre);
  const json& r = cam_node["rotation"];  // x, y, z, w
  const Eigen::Quaterniond q(r[3].get<double>(), r[0].get<double>(), r[1].get<double>(), r[2].get<double>());
  EXPECT_NEAR(q.norm(), 1.0, kExact);
  // A glTF camera looks along its -z with +y up the image: down (-y in glTF axes), north
  // (-z in glTF axes) up the image.
  EXPECT_LT((q * Eigen::Vector3d(0, 0, -1) - Eigen::Vector3d(0, -1, 0)).norm(), kExact);
  EXPECT_LT((q * Eigen::Vector3d(0, 1, 0) - Eigen::Vector3d(0, 0, -1)).norm(), kExact);
}

TEST(GltfExport, SceneRefusesBrokenNodes) {
  test::ScratchDir dir("gltf_scene_bad");
  const DenseMesh m = utm_grid();
  GltfScene scene;
  scene.meshes.push_back({"m", &m});
  scene.nodes.push_back({.name = "ghost", .mesh = 1});
  EXPECT_THROW(write_glb(dir / "s.glb", scene, utm_frame()), InputError);
  scene.nodes = {{.name = "m", .mesh = 0, .extras_json = "[1, 2]"}};
  EXPECT_THROW(write_glb(dir / "s.glb", scene, utm_frame()), InputError);
  scene.nodes = {{.name = "skew", .rotation = Eigen::Matrix3d(Eigen::Vector3d(1, 1, 1).asDiagonal() * 2.0)}};
  EXPECT_THROW(write_glb(dir / "s.glb", scene, utm_frame()), InputError);
  scene.nodes = {{.name = "m", .mesh = 0}};
  scene.meshes[0].colour = std::array<double, 4>{1.5, 0, 0, 1};
  EXPECT_THROW(write_glb(dir / "s.glb", scene, utm_frame()), InputError);
  EXPECT_FALSE(fs::exists(dir / "s.glb"));
}

}  // namespace
}  // namespace strata
