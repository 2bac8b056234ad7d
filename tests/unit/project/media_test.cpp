// verify_media (project/media.hpp): a photo altered, cut or deleted in media/ is
// named and refused; an intact one passes, and is read in full only when its
// size or modification time changed since the last check.
#include "core/error.hpp"
#include "core/hash.hpp"
#include "project/media.hpp"
#include "project/records.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <fstream>

namespace strata {
namespace {

namespace fs = std::filesystem;

// A photo stored as the importer does, with a modification time an hour ago (a file
// modified within the last seconds is hashed at every check, see media.cpp).
ImageRecord store_photo(const fs::path& project, const std::string& name, const std::string& bytes) {
  const std::string sha = sha256_hex(bytes);
  ImageRecord r;
  r.name = name;
  r.sha256 = sha;
  r.media_path = media_relative_path(sha, name);
  r.bytes = std::int64_t(bytes.size());
  test::write_text(project / r.media_path, bytes);
  fs::last_write_time(project / r.media_path, fs::file_time_type::clock::now() - std::chrono::hours(1));
  return r;
}

void overwrite(const fs::path& file, const std::string& bytes) {
  const auto before = fs::last_write_time(file);
  test::write_text(file, bytes);
  // An editor's save happens long after the import: the time moves on.
  fs::last_write_time(file, before + std::chrono::seconds(10));
}

std::string refusal(const fs::path& project, const std::vector<ImageRecord>& photos) {
  try {
    verify_media(project, photos);
  } catch (const IoError& e) {
    return e.what();
  }
  return "";
}

TEST(VerifyMedia, IntactPhotosPassAndAreHashedOnce) {
  test::ScratchDir dir("media_ok");
  const std::vector<ImageRecord> photos = {store_photo(dir.path(), "IMG_0001.JPG", "first photo"),
                                           store_photo(dir.path(), "IMG_0002.JPG", "second photo")};
  auto s = verify_media(dir.path(), photos);
  EXPECT_EQ(s.photos, 2u);
  EXPECT_EQ(s.hashed, 2u);
  s = verify_media(dir.path(), photos);
  EXPECT_EQ(s.hashed, 0u) << "size and time unchanged since the last check: no need to read the photos";
  fs::remove_all(dir / "cache");  // the record is a cache: without it, photos are read again
  EXPECT_EQ(verify_media(dir.path(), photos).hashed, 2u);
}

TEST(VerifyMedia, AlteredPhotoOfTheSameSizeIsNamed) {
  test::ScratchDir dir("media_altered");
  const std::vector<ImageRecord> photos = {store_photo(dir.path(), "IMG_0001.JPG", "first photo"),
                                           store_photo(dir.path(), "IMG_0002.JPG", "second photo")};
  verify_media(dir.path(), photos);  // checked once, recorded
  overwrite(dir / photos[1].media_path, "second phot0");
  const std::string msg = refusal(dir.path(), photos);
  EXPECT_NE(msg.find("IMG_0002.JPG"), std::string::npos) << msg;
  EXPECT_NE(msg.find(photos[1].media_path), std::string::npos) << msg;
  EXPECT_NE(msg.find("SHA-256"), std::string::npos) << msg;
  EXPECT_EQ(msg.find("IMG_0001.JPG"), std::string::npos) << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  // Still refused the next time: a failed check records nothing.
  EXPECT_NE(refusal(dir.path(), photos).find("IMG_0002.JPG"), std::string::npos);
}

TEST(VerifyMedia, CutAndMissingPhotosAreNamed) {
  test::ScratchDir dir("media_missing");
  const std::vector<ImageRecord> photos = {store_photo(dir.path(), "IMG_0001.JPG", "first photo"),
                                           store_photo(dir.path(), "IMG_0002.JPG", "second photo")};
  overwrite(dir / photos[0].media_path, "first");
  fs::remove(dir / photos[1].media_path);
  const std::string msg = refusal(dir.path(), photos);
  EXPECT_NE(msg.find("2 of 2 photo(s)"), std::string::npos) << msg;
  EXPECT_NE(msg.find("IMG_0001.JPG (" + photos[0].media_path + ") was altered: 5 bytes, 11 at import"),
            std::string::npos)
      << msg;
  EXPECT_NE(msg.find("IMG_0002.JPG (" + photos[1].media_path + ") is missing"), std::string::npos) << msg;
}

}  // namespace
}  // namespace strata
