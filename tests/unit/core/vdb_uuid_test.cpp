// The UUID OpenVDB draws at random for every file is replaced by one derived from the
// content, so that identical grids give identical files (docs/reliability.md,
// "Reproducible results").
#include "core/error.hpp"
#include "core/vdb_uuid.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <string>

namespace strata {
namespace {

namespace fs = std::filesystem;

// The first bytes of an OpenVDB file as io::Archive writes them, then `body`.
std::string vdb_bytes(const std::string& uuid, const std::string& body) {
  std::string h("\x20\x42\x44\x56\0\0\0\0\xe0\0\0\0\x0a\0\0\0\0\0\0\0\x01", 21);
  return h + uuid + body;
}

fs::path write(const std::string& name, const std::string& bytes) {
  const fs::path p = fs::temp_directory_path() / ("strata_vdb_uuid_" + name);
  std::ofstream(p, std::ios::binary) << bytes;
  return p;
}

std::string read(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(VdbUuid, SameGridsGiveTheSameFileAndOtherGridsAnother) {
  const auto a = write("a.vdb", vdb_bytes("442d9329-f2ba-4e65-bca6-c6f331fe6b4a", "grids"));
  const auto b = write("b.vdb", vdb_bytes("0b1e2c4d-0000-4111-8222-123456789abc", "grids"));
  const auto c = write("c.vdb", vdb_bytes("442d9329-f2ba-4e65-bca6-c6f331fe6b4a", "other grids"));
  make_vdb_uuid_from_content(a);
  make_vdb_uuid_from_content(b);
  make_vdb_uuid_from_content(c);
  const std::string ra = read(a), rb = read(b), rc = read(c);
  EXPECT_EQ(ra, rb);
  EXPECT_NE(ra.substr(21, 36), rc.substr(21, 36));
  // Still a UUID in OpenVDB's form: 8-4-4-4-12 hex digits, version 4; the rest untouched.
  const std::string u = ra.substr(21, 36);
  EXPECT_EQ(u[8], '-');
  EXPECT_EQ(u[13], '-');
  EXPECT_EQ(u[14], '4');
  EXPECT_EQ(u[18], '-');
  EXPECT_EQ(u[23], '-');
  EXPECT_NE(std::string("89ab").find(u[19]), std::string::npos) << u;
  EXPECT_EQ(ra.substr(0, 21), vdb_bytes("", "").substr(0, 21));
  EXPECT_EQ(ra.substr(57), "grids");
  // Idempotent: a second pass leaves the file as it is.
  make_vdb_uuid_from_content(a);
  EXPECT_EQ(read(a), ra);
  for (const auto& p : {a, b, c}) fs::remove(p);
}

TEST(VdbUuid, AFileThatIsNotOpenVdbIsRefusedAndLeftAlone) {
  const std::string text = "not a VDB file, but long enough to hold a header and a UUID ...";
  const auto p = write("text.vdb", text);
  try {
    make_vdb_uuid_from_content(p);
    ADD_FAILURE() << "a text file was accepted";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos) << e.what();
  }
  EXPECT_EQ(read(p), text);
  fs::remove(p);
}

}  // namespace
}  // namespace strata
