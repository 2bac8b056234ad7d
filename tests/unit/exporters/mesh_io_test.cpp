// writer.ply / writer.obj round trips: header, counts, and full precision of
// site-CRS coordinates with a large (UTM-sized) offset; exporter.obj (the model for
// viewers, untextured and textured) parsed back by the test itself.
#include "core/error.hpp"
#include "exporters/mesh/mesh_writers.hpp"
#include "importers/mesh/ply_mesh.hpp"
#include "support/obj_file.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>

#include <map>
#include <sstream>

namespace strata {
namespace {

constexpr double kCrsTolerance = 1e-6;    // metres: doubles keep micrometres at 1e7 m
constexpr double kLocalTolerance = 1e-5;  // metres: float in the site frame, |x| < 100 m
const Eigen::Vector3d kOrigin(512345.678901, 4123456.789012, 234.5);  // E, N, Z metres

ExportFrame frame_at(const Eigen::Vector3d& site_origin, const std::string& crs = "EPSG:32636") {
  ExportFrame frame;
  frame.site_origin = site_origin;
  frame.crs = crs;
  return frame;
}

DenseMesh small_mesh() {
  DenseMesh m;
  m.vertices = {{0.0, 0.0, 0.0}, {1.234567, 0.000123, -0.5}, {0.1, 2.000001, 0.25}, {-3.5, 7.25, 1.0}};
  m.colours = {Rgb8(255, 0, 0), Rgb8(0, 255, 0), Rgb8(0, 0, 255), Rgb8(10, 20, 30)};
  m.faces = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

TEST(DenseMeshIo, PlyRoundTripKeepsCrsCoordinatesInDouble) {
  test::ScratchDir dir("dense_ply");
  const DenseMesh m = small_mesh();
  write_ply(dir / "mesh.ply", m, frame_at(kOrigin));
  // Only the mesh: its temporary file took the final name.
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(dir.path())) files.push_back(e.path().filename().string());
  EXPECT_EQ(files, std::vector<std::string>{"mesh.ply"});
  const PlyContents r = read_ply(dir / "mesh.ply");
  ASSERT_GE(r.header.size(), 3u);
  EXPECT_EQ(r.header[0], "ply");
  EXPECT_EQ(r.header[1], "format binary_little_endian 1.0");
  EXPECT_NE(std::find(r.header.begin(), r.header.end(), "element vertex 4"), r.header.end());
  EXPECT_NE(std::find(r.header.begin(), r.header.end(), "property double x"), r.header.end());
  EXPECT_NE(std::find(r.header.begin(), r.header.end(), "element face 2"), r.header.end());
  EXPECT_TRUE(r.double_coordinates);
  EXPECT_FALSE(r.has_offset_comment);
  EXPECT_EQ(r.crs, "EPSG:32636");
  ASSERT_EQ(r.mesh.vertices.size(), m.vertices.size());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    EXPECT_LT((r.mesh.vertices[i] - (m.vertices[i] + kOrigin)).norm(), kCrsTolerance) << i;
    EXPECT_EQ(r.mesh.colours[i], m.colours[i]);
  }
  EXPECT_EQ(r.mesh.faces, m.faces);
}

TEST(DenseMeshIo, PlyLocalFloatCarriesOffsetComment) {
  test::ScratchDir dir("dense_ply_local");
  DenseMesh m = small_mesh();
  m.faces.clear();  // a point cloud
  m.normals.assign(m.vertices.size(), Eigen::Vector3f::UnitZ());
  ExportFrame frame;
  frame.crs_coordinates = false;
  frame.site_origin = kOrigin;
  write_ply(dir / "points.ply", m, frame);
  const PlyContents r = read_ply(dir / "points.ply");
  EXPECT_FALSE(r.double_coordinates);
  ASSERT_TRUE(r.has_offset_comment);
  EXPECT_LT((r.offset - kOrigin).norm(), kCrsTolerance);
  ASSERT_EQ(r.mesh.vertices.size(), m.vertices.size());
  EXPECT_TRUE(r.mesh.faces.empty());
  ASSERT_EQ(r.mesh.normals.size(), m.vertices.size());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    EXPECT_LT((r.mesh.vertices[i] - m.vertices[i]).norm(), kLocalTolerance) << i;
  }
}

// A PLY from another program, or a damaged copy: counts that the data cannot hold,
// faces naming vertices that do not exist, a header without its end are refused with
// reader.ply's error before they size an allocation or index a vertex (found by
// fuzzing, tests/fuzz/corpus/ply).
TEST(DenseMeshIo, PlyReaderRefusesCountsAndIndicesTheFileDoesNotHold) {
  test::ScratchDir dir("dense_ply_bad");
  write_ply(dir / "good.ply", small_mesh(), ExportFrame{});
  const std::string good = test::read_text(dir / "good.ply");
  auto error_of = [&](const std::string& bytes) -> std::string {
    test::write_text(dir / "bad.ply", bytes);
    try {
      read_ply(dir / "bad.ply");
    } catch (const IoError& e) {
      return e.what();
    }
    return "accepted";
  };
  auto replaced = [&](const std::string& from, const std::string& to) {
    std::string s = good;
    const auto at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, from.size(), to);
  };
  EXPECT_NE(error_of(replaced("element vertex 4", "element vertex 400000000000")).find("more than the file holds"),
            std::string::npos);
  EXPECT_NE(error_of(replaced("element face 2", "element face 9000000000")).find("more than the file holds"),
            std::string::npos);
  EXPECT_NE(error_of(replaced("element vertex 4", "element vertex -1")).find("element count '-1' is not a number"),
            std::string::npos);
  // The last index of the last face (int32, little-endian) names vertex 99 of 4.
  std::string far = good;
  far.replace(far.size() - 4, 4, std::string("\x63\0\0\0", 4));
  EXPECT_NE(error_of(far).find("face 1 names vertex 99, but there are 4 vertices"), std::string::npos);
  EXPECT_NE(error_of(good.substr(0, good.find("end_header"))).find("no end_header"), std::string::npos);
  EXPECT_EQ(error_of(good), "accepted");
  // The shared header grammar: a file that is not a PLY, a line outside the grammar,
  // faces before the vertices; each named with its header line.
  EXPECT_NE(error_of("plx\n" + good.substr(4)).find("it must start with a line 'ply'"), std::string::npos);
  EXPECT_NE(error_of(replaced("end_header", "frobnicate 1\nend_header")).find("unknown header line 'frobnicate 1'"),
            std::string::npos);
  {
    const auto v = good.find("element vertex"), f = good.find("element face"), e = good.find("end_header");
    const std::string faces_first = good.substr(0, v) + good.substr(f, e - f) + good.substr(v, f - v) + good.substr(e);
    const std::string err = error_of(faces_first);
    EXPECT_NE(err.find("is not supported here"), std::string::npos) << err;
    EXPECT_NE(err.find("line "), std::string::npos) << err;
  }
  // Colour without "red" (it wrote past the empty colour array).
  test::write_text(dir / "green.ply", replaced("property uchar red\n", "property uchar alpha\n"));
  const PlyContents green = read_ply(dir / "green.ply");
  ASSERT_EQ(green.mesh.colours.size(), 4u);
  EXPECT_EQ(green.mesh.colours[0][0], 0);
  EXPECT_EQ(green.mesh.colours[0][1], 0);  // small_mesh's first vertex is pure red
}

TEST(DenseMeshIo, ObjHasVerticesFacesAndOffset) {
  test::ScratchDir dir("dense_obj");
  ExportFrame frame;
  frame.site_origin = kOrigin;
  write_obj(dir / "mesh.obj", small_mesh(), frame);
  const std::string text = test::read_text(dir / "mesh.obj");
  EXPECT_NE(text.find("v 512345.678901 4123456.789012 234.500000 1.0000 0.0000 0.0000\n"), std::string::npos);
  EXPECT_NE(text.find("f 1 3 4\n"), std::string::npos);
}

// ---- exporter.obj ---------------------------------------------------------------

// Every face corner names an existing v (and vt, vn when the file has them).
void expect_indices_in_range(const test::ObjFile& o) {
  for (const auto& face : o.f) {
    for (const auto& c : face) {
      EXPECT_GE(c[0], 1);
      EXPECT_LE(c[0], int(o.v.size()));
      if (!o.vt.empty()) {
        EXPECT_TRUE(c[1] >= 1 && c[1] <= int(o.vt.size())) << c[1];
      }
      if (!o.vn.empty()) {
        EXPECT_TRUE(c[2] >= 1 && c[2] <= int(o.vn.size())) << c[2];
      }
    }
  }
}

std::vector<std::string> files_in(const std::filesystem::path& dir) {
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(dir)) files.push_back(e.path().filename().string());
  std::sort(files.begin(), files.end());
  return files;
}

// The CLI's test meshes sit at E 734000, N 4174000: float32 alone is a quarter metre off.
const Eigen::Vector3d kUtmSiteOrigin(734000.0, 4174000.0, 1450.0);
constexpr double kViewerTolerance = 1e-4;  // metres: what the local origin must preserve in float32

DenseMesh utm_mesh() {
  DenseMesh m = small_mesh();
  m.normals = {{0, 0, 1}, {0, 0, 2}, {0, 0, 0}, {0.6f, 0, 0.8f}};  // unnormalised, zero: written unit length
  return m;
}

TEST(ObjModelExport, VerticesComeBackThroughTheStatedOriginInFloat) {
  test::ScratchDir dir("obj_model");
  const DenseMesh m = utm_mesh();
  const ObjModelFiles files = write_obj_model(dir / "l1.obj", m, frame_at(kUtmSiteOrigin));
  EXPECT_EQ(files_in(dir.path()), std::vector<std::string>{"l1.obj"});
  EXPECT_TRUE(files.mtl.empty());
  const test::ObjFile o = test::read_obj(dir / "l1.obj");
  EXPECT_EQ(o.comments.at("crs"), "EPSG:32636");
  EXPECT_NE(o.comments.at("axes:").find("x = E, y = N, z = Z (up)"), std::string::npos);
  // Box centre in site CRS (733998.867, 4174003.625, 1450.25) -> whole metres.
  const Eigen::Vector3d origin = o.origin;
  EXPECT_EQ(origin, Eigen::Vector3d(733999, 4174004, 1450));
  EXPECT_EQ(files.origin, origin);
  ASSERT_EQ(o.v.size(), m.vertices.size());
  ASSERT_EQ(o.rgb.size(), m.vertices.size());
  ASSERT_EQ(o.vn.size(), m.vertices.size());
  ASSERT_EQ(o.f.size(), m.faces.size());
  EXPECT_TRUE(o.vt.empty());
  EXPECT_TRUE(o.mtllib.empty());
  expect_indices_in_range(o);
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    // What a float32 reader holds, back to site CRS through the stated origin.
    const Eigen::Vector3d back = origin + o.v[i].cast<float>().cast<double>();
    EXPECT_LT((back - (m.vertices[i] + kUtmSiteOrigin)).cwiseAbs().maxCoeff(), kViewerTolerance) << i;
    EXPECT_LT((o.rgb[i] - m.colours[i].cast<double>() / 255.0).cwiseAbs().maxCoeff(), 1e-4) << i;
    EXPECT_NEAR(o.vn[i].norm(), 1.0, 1e-3) << i;
  }
  EXPECT_NEAR(o.vn[3].x(), 0.6, 1e-4);
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(o.f[f][k][0], m.faces[f][k] + 1);
      EXPECT_EQ(o.f[f][k][2], m.faces[f][k] + 1);
    }
  }
}

TEST(ObjModelExport, TexturedMeshHasUvsOneGroupPerAtlasAndItsMaterialFiles) {
  test::ScratchDir dir("obj_model_textured");
  DenseMesh m = utm_mesh();
  m.colours.clear();  // a textured mesh has none (texture_atlas.hpp)
  MeshTexture t;
  t.uv = {{0.0f, 0.0f}, {1.0f, 0.25f}, {0.5f, 1.0f}, {0.125f, 0.75f}};
  t.face_image = {1, 0};
  t.images = {"first atlas bytes", "second atlas bytes"};
  t.mime_type = "image/png";
  const ObjModelFiles files = write_obj_model(dir / "l1.obj", m, frame_at(kUtmSiteOrigin, ""), &t);
  EXPECT_EQ(files_in(dir.path()), (std::vector<std::string>{"l1.mtl", "l1.obj", "l1_atlas1.png", "l1_atlas2.png"}));
  EXPECT_EQ(test::read_text(dir / "l1_atlas2.png"), t.images[1]);
  const test::ObjFile o = test::read_obj(dir / "l1.obj");
  EXPECT_EQ(o.mtllib, "l1.mtl");
  ASSERT_EQ(o.vt.size(), m.vertices.size());
  ASSERT_EQ(o.f.size(), m.faces.size());
  EXPECT_TRUE(o.rgb.empty());
  expect_indices_in_range(o);
  for (std::size_t i = 0; i < o.vt.size(); ++i) {
    EXPECT_TRUE(o.vt[i].x() >= 0 && o.vt[i].x() <= 1 && o.vt[i].y() >= 0 && o.vt[i].y() <= 1) << i;
    // OBJ's v = 0 is the bottom of the image, glTF's (the texture's) the top.
    EXPECT_NEAR(o.vt[i].x(), t.uv[i].x(), 1e-6);
    EXPECT_NEAR(o.vt[i].y(), 1.0 - t.uv[i].y(), 1e-6);
  }
  // Faces grouped by atlas: face 1 (atlas 1) first, then face 0 (atlas 2).
  EXPECT_EQ(o.face_material, (std::vector<std::string>{"atlas_1", "atlas_2"}));
  EXPECT_EQ(o.f[0][0][0], m.faces[1][0] + 1);
  EXPECT_EQ(o.f[0][0][1], m.faces[1][0] + 1);
  // Each material of the .mtl names an image that exists beside it.
  std::istringstream mtl(test::read_text(dir / "l1.mtl"));
  std::string line, material;
  std::map<std::string, std::string> map_kd;
  while (std::getline(mtl, line)) {
    std::istringstream ls(line);
    std::string tag, value;
    ls >> tag >> value;
    if (tag == "newmtl") material = value;
    if (tag == "map_Kd") map_kd[material] = value;
  }
  ASSERT_EQ(map_kd.size(), 2u);
  for (const auto& [name, image] : map_kd) EXPECT_TRUE(std::filesystem::exists(dir / image)) << name << " " << image;
  EXPECT_EQ(map_kd["atlas_1"], "l1_atlas1.png");
}

TEST(ObjModelExport, AFailureLeavesNoFileBehind) {
  test::ScratchDir dir("obj_model_unwritable");
  test::write_text(dir / "plain_file", "a file, not a folder");
  const std::filesystem::path out = dir / "plain_file" / "l1.obj";  // refused even to root
  EXPECT_THROW(write_obj_model(out, small_mesh(), ExportFrame{}), IoError);
  // The .obj's name taken by a folder: refused before any rename, the images and .mtl
  // staged (and renamed before the .obj) are removed too.
  std::filesystem::create_directories(dir / "l1.obj");
  MeshTexture t;
  t.uv.assign(4, Eigen::Vector2f(0.5f, 0.5f));
  t.face_image = {0, 0};
  t.images = {"atlas"};
  EXPECT_THROW(write_obj_model(dir / "l1.obj", small_mesh(), ExportFrame{}, &t), IoError);
  EXPECT_EQ(files_in(dir.path()), (std::vector<std::string>{"l1.obj", "plain_file"}));
  DenseMesh points = small_mesh();
  points.faces.clear();
  EXPECT_THROW(write_obj_model(dir / "points.obj", points, ExportFrame{}), InputError);
}

}  // namespace
}  // namespace strata
