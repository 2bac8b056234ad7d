#include "core/error.hpp"
#include "core/hash.hpp"
#include "importer_fixture.hpp"
#include "importers/photos/exif.hpp"
#include "importers/photos/photo_importer.hpp"

#include <fstream>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::ImporterTest;

TEST_F(ImporterTest, PhotosAreStoredUnderTheirHashAndReimportIsANoOp) {
  const std::vector<fs::path> files = {make_photo("a.jpg", 1), make_photo("b.jpg", 2)};
  auto s = import_photos(project(), {"L1", false}, files);
  EXPECT_EQ(s.imported, 2);
  EXPECT_EQ(s.without_exif.size(), 2u);  // OpenCV writes no EXIF
  const auto images = list_images(db());
  ASSERT_EQ(images.size(), 2u);
  for (const auto& im : images) {
    EXPECT_TRUE(fs::exists(project().dir() / im.media_path));
    EXPECT_EQ(sha256_file(project().dir() / im.media_path), im.sha256);
    EXPECT_EQ(im.media_path.substr(0, 9), "media/" + im.sha256.substr(0, 2) + "/");
    EXPECT_EQ(im.width, 160);
    EXPECT_EQ(im.height, 120);
  }
  const std::string before = dump();
  const std::string media_before = test::tree_fingerprint(project().media_dir());
  s = import_photos(project(), {"L1", false}, files);
  EXPECT_EQ(s.imported, 0);
  EXPECT_EQ(s.already_present.size(), 2u);
  EXPECT_EQ(dump(), before);
  EXPECT_EQ(test::tree_fingerprint(project().media_dir()), media_before);
  // The same content under another name in another layer is refused, naming the
  // layer that holds it (a photo records one state of the surface), and with
  // --skip-bad listed as bad.
  fs::copy_file(files[0], scratch() / "in" / "copy.jpg");
  try {
    import_photos(project(), {"L2", false}, {scratch() / "in" / "copy.jpg"});
    FAIL() << "a photo of layer L1 was accepted into L2";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("copy.jpg: the same photo is already in layer L1 (as a.jpg)"), std::string::npos) << msg;
  }
  EXPECT_EQ(dump(), before);
  s = import_photos(project(), {"L2", true}, {scratch() / "in" / "copy.jpg"});
  EXPECT_EQ(s.imported, 0);
  ASSERT_EQ(s.bad.size(), 1u);
  EXPECT_NE(s.bad[0].find("already in layer L1"), std::string::npos) << s.bad[0];
  EXPECT_EQ(list_images(db()).size(), 2u);
}

TEST_F(ImporterTest, BadBatchImportsNothingAndNamesEachBadFile) {
  import_photos(project(), {"L1", false}, {make_photo("first.jpg", 7)});
  const std::string before = dump();
  const std::string media_before = test::tree_fingerprint(project().media_dir());

  const fs::path good = make_photo("good.jpg", 3);
  const fs::path truncated = make_photo("truncated.jpg", 4);
  fs::resize_file(truncated, fs::file_size(truncated) / 2);
  const fs::path text = scratch() / "in" / "notes.jpg";
  std::ofstream(text) << "field notes, not a photo\n";
  const fs::path missing = scratch() / "in" / "missing.jpg";

  try {
    import_photos(project(), {"L1", false}, {good, truncated, text, missing});
    FAIL() << "bad batch accepted";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("truncated.jpg: truncated JPEG"), std::string::npos) << msg;
    EXPECT_NE(msg.find("notes.jpg: not a JPEG"), std::string::npos) << msg;
    EXPECT_NE(msg.find("missing.jpg: does not exist"), std::string::npos) << msg;
    EXPECT_EQ(msg.find("good.jpg"), std::string::npos) << msg;
  }
  EXPECT_EQ(dump(), before);
  EXPECT_EQ(test::tree_fingerprint(project().media_dir()), media_before);

  auto s = import_photos(project(), {"L1", true}, {good, truncated, text, missing});
  EXPECT_EQ(s.imported, 1);
  EXPECT_EQ(s.bad.size(), 3u);
}

TEST_F(ImporterTest, UnknownLayerIsRefused) {
  EXPECT_THROW(import_photos(project(), {"L9", false}, {make_photo("x.jpg", 9)}), InputError);
}

TEST(Exif, FocalPriorFromTheSensorListFocalPlaneAnd35mm) {
  PhotoMetadata m;
  m.width = 2136;
  m.height = 1424;
  m.make = "Canon";
  m.model = "Canon EOS DIGITAL REBEL XSi";
  m.focal_mm = 30.0;
  FocalPrior p = focal_prior(m);
  EXPECT_EQ(p.source, "sensor_list");
  EXPECT_NEAR(*p.focal_px, 30.0 / 22.2 * 2136, 1e-9);

  m.model = "Unknown Camera 3000";
  m.exif_width = 4272;  // the original size: this file is a half-size copy
  m.focal_plane_x_res = 4272 / 22.2 * 25.4;  // pixels per inch
  m.focal_plane_unit_mm = 25.4;
  p = focal_prior(m);
  EXPECT_EQ(p.source, "focal_plane");
  EXPECT_NEAR(*p.sensor_width_mm, 22.2, 1e-9);

  m.focal_mm.reset();
  m.focal_35mm = 48;
  p = focal_prior(m);
  EXPECT_EQ(p.source, "35mm");
  EXPECT_NEAR(*p.focal_px, 48 / 43.2666 * std::hypot(2136.0, 1424.0), 1e-6);
}

TEST_F(ImporterTest, RealPhotosFromTheCoprSet) {
  const fs::path dir = test::shared_data_dir() / "copr" / "images";
  if (!fs::exists(dir)) GTEST_SKIP() << "shared data not present: " << dir;
  const auto s = import_photos(project(), {"L1", false}, {dir / "IMG_0022.jpg"});
  EXPECT_EQ(s.imported, 1);
  const auto im = list_images(db()).front();
  EXPECT_EQ(im.captured_at, "2009-09-02T07:38:43");
  const auto cam = find_camera(db(), *im.camera_id);
  ASSERT_TRUE(cam);
  EXPECT_EQ(cam->focal_source, "sensor_list");
  EXPECT_NEAR(*cam->focal_px, 30.0 / 22.2 * 2136, 1e-6);
}

}  // namespace
}  // namespace strata
