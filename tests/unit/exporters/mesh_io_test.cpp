// writer.ply / writer.obj round trips: header, counts, and full precision of
// site-CRS coordinates with a large (UTM-sized) offset.
#include "core/error.hpp"
#include "exporters/mesh/mesh_writers.hpp"
#include "importers/mesh/ply_mesh.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>

namespace strata {
namespace {

constexpr double kCrsTolerance = 1e-6;    // metres: doubles keep micrometres at 1e7 m
constexpr double kLocalTolerance = 1e-5;  // metres: float in the site frame, |x| < 100 m
const Eigen::Vector3d kOrigin(512345.678901, 4123456.789012, 234.5);  // E, N, Z metres

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
  ExportFrame frame;
  frame.site_origin = kOrigin;
  frame.crs = "EPSG:32636";
  write_ply(dir / "mesh.ply", m, frame);
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

}  // namespace
}  // namespace strata
