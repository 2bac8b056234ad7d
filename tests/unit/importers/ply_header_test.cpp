// ply::read_header: the one PLY header grammar of the mesh and point-cloud readers.
#include "core/error.hpp"
#include "importers/ply/ply_header.hpp"

#include <gtest/gtest.h>

#include <sstream>

namespace strata {
namespace {

constexpr const char* kStage = "importer.test";

ply::Header header_of(const std::string& text) {
  std::istringstream in(text);
  return ply::read_header(in, kStage, "scan.ply");
}

std::string error_of(const std::string& text) {
  try {
    header_of(text);
  } catch (const InputError& e) {
    return e.what();
  }
  return "accepted";
}

TEST(PlyHeader, DescribesFormatElementsListsCommentsAndWhereTheBodyStarts) {
  const std::string head =
      "ply\r\nformat binary_big_endian 1.0\ncomment crs EPSG:32636\nobj_info scanner\n"
      "element vertex 3\nproperty double x\nproperty float32 y\nproperty uchar red\n"
      "element face 1\nproperty list uint8 int32 vertex_indices\nend_header\n";
  const ply::Header h = header_of(head + "BODY");
  EXPECT_EQ(h.format, ply::Format::binary_big_endian);
  EXPECT_EQ(h.line_count, 11u);
  EXPECT_EQ(h.body_offset, head.size());
  ASSERT_EQ(h.comments.size(), 1u);
  EXPECT_EQ(h.comments[0], "crs EPSG:32636");
  EXPECT_EQ(h.lines[0], "ply");  // without its "\r"
  ASSERT_EQ(h.elements.size(), 2u);
  const ply::Element* vertex = h.find("vertex");
  ASSERT_NE(vertex, nullptr);
  EXPECT_EQ(vertex->count, 3u);
  EXPECT_EQ(vertex->line, 5u);
  ASSERT_EQ(vertex->properties.size(), 3u);
  EXPECT_EQ(vertex->properties[1].name, "y");
  EXPECT_EQ(vertex->properties[1].type, ply::Type::float32);
  EXPECT_EQ(vertex->properties[1].line, 7u);
  const ply::Property& list = h.elements[1].properties.at(0);
  EXPECT_TRUE(list.list);
  EXPECT_EQ(list.count_type, ply::Type::uint8);
  EXPECT_EQ(list.type, ply::Type::int32);
  EXPECT_EQ(h.find("edge"), nullptr);
}

TEST(PlyHeader, ALineOutsideTheGrammarIsRefusedNamingTheFileAndLine) {
  const std::string start = "ply\nformat ascii 1.0\n";
  EXPECT_EQ(error_of("PLY\n"), "importer.test: scan.ply: line 1: not a PLY file: it must start with a line 'ply'");
  EXPECT_NE(error_of(start + "element vertex -1\nend_header\n").find("line 3: element count '-1' is not a number"),
            std::string::npos);
  EXPECT_NE(error_of(start + "property float x\nend_header\n").find("line 3: a property before any element"),
            std::string::npos);
  EXPECT_NE(error_of(start + "element vertex 1\nproperty list float int i\nend_header\n")
                .find("line 4: unknown property type"),
            std::string::npos);
  EXPECT_NE(error_of(start + "texture none\nend_header\n").find("line 3: unknown header line 'texture none'"),
            std::string::npos);
  EXPECT_NE(error_of("ply\nelement vertex 0\nend_header\n").find("line 3: the header has no 'format' line"),
            std::string::npos);
  EXPECT_EQ(error_of(start + "element vertex 0\n"),
            "importer.test: scan.ply: the header has no end_header line: not a PLY file, or cut short");
}

}  // namespace
}  // namespace strata
