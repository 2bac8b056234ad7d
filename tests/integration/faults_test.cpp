// The machine misbehaves (docs/reliability.md): a disk that fills part-way
// through a product, a read-only project folder, a project folder moved
// after processing, a photo in media/ altered or deleted, corrupted cache files.
// Each case asserts the message and that the project records what it did before.
#include "integration/field_project.hpp"

#include <gtest/gtest.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>

#include <sys/mount.h>
#include <sys/statvfs.h>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::run_strata;

// Bytes left free on the small file system when the products stage starts: less
// than one DTM (1000 x 1000 Float32 cells and more), more than a lock file and a
// few database pages.
constexpr std::uintmax_t kFreeBytesLeft = 256 * 1024;

class Faults : public ::testing::Test {
 protected:
  // One synthetic layer processed to its products, made once for every process of the
  // suite (support/shared_scene.hpp); each test works on its own copy.
  static void SetUpTestSuite() {
    scratch_ = new test::ScratchDir("faults");
    try {
      shared_ = test::shared_project("faults", 1, 12, 5, std::vector<std::string>{});
    } catch (const std::exception& e) {
      setup_error_ = e.what();
    }
  }
  // A failure while the shared project is made fails every test (gtest would report
  // them as skipped, and ctest count a skip as no failure).
  void SetUp() override {
    if (!setup_error_.empty()) FAIL() << "the shared project could not be made: " << setup_error_;
  }
  static void TearDownTestSuite() {
    delete scratch_;
    scratch_ = nullptr;
  }
  static fs::path copy_template(const fs::path& site) {
    fs::remove_all(site);
    test::copy_scene(shared_ / "template", site);
    return site;
  }
  static fs::path scratch() { return scratch_->path(); }
  static test::ScratchDir* scratch_;
  static fs::path shared_;
  static std::string setup_error_;
};
test::ScratchDir* Faults::scratch_ = nullptr;
fs::path Faults::shared_;
std::string Faults::setup_error_;

// A mount the test made, undone when it ends.
class Mount {
 public:
  Mount(const fs::path& target) : target_(target) {}
  ~Mount() {
    if (mounted_) umount2(target_.c_str(), MNT_DETACH);
  }
  // Empty when mounted; else why not (the test skips).
  std::string tmpfs(std::uintmax_t bytes) {
    fs::create_directories(target_);
    const std::string options = "size=" + std::to_string(bytes);
    if (mount("tmpfs", target_.c_str(), "tmpfs", 0, options.c_str()) != 0) return std::strerror(errno);
    mounted_ = true;
    return "";
  }
  std::string read_only_bind(const fs::path& source) {
    fs::create_directories(target_);
    if (mount(source.c_str(), target_.c_str(), nullptr, MS_BIND, nullptr) != 0) return std::strerror(errno);
    mounted_ = true;
    if (mount(nullptr, target_.c_str(), nullptr, MS_BIND | MS_REMOUNT | MS_RDONLY, nullptr) != 0)
      return std::strerror(errno);
    return "";
  }

 private:
  fs::path target_;
  bool mounted_ = false;
};

// Fills the file system holding `dir` so that `left` bytes stay free.
void fill_leaving(const fs::path& dir, std::uintmax_t left) {
  struct statvfs s {};
  ASSERT_EQ(statvfs(dir.c_str(), &s), 0);
  const std::uintmax_t free_bytes = std::uintmax_t(s.f_bavail) * s.f_frsize;
  ASSERT_GT(free_bytes, left);
  std::ofstream filler(dir / "filler", std::ios::binary);
  const std::string block(64 * 1024, 'x');
  std::uintmax_t todo = free_bytes - left;
  while (todo > 0) {
    const std::size_t n = std::size_t(std::min<std::uintmax_t>(todo, block.size()));
    filler.write(block.data(), std::streamsize(n));
    todo -= n;
  }
}

void corrupt_middle(const fs::path& file) {
  std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
  f.seekg(0, std::ios::end);
  const auto size = std::streamoff(f.tellg());
  f.seekp(size / 2);
  const std::string junk(std::size_t(std::min<std::streamoff>(size / 4 + 1, 4096)), '\x5a');
  f.write(junk.data(), std::streamsize(junk.size()));
}

// A tmpfs at `disk` with room for `project` twice over and its next products: empty
// when mounted, else why not.
std::string mount_room_for(Mount& disk, const fs::path& project) {
  std::uintmax_t project_bytes = 0;
  for (const auto& e : fs::recursive_directory_iterator(project))
    if (e.is_regular_file()) project_bytes += e.file_size();
  return disk.tmpfs(project_bytes * 2 + (64u << 20));
}

// Runs `args`, a command writing into `site` on the file system mounted at `mnt`,
// with only kFreeBytesLeft free: it must fail with one line naming a file of the
// site and "No space left on device", leaving the project and the files under
// `watched` as they were; with room again, the same command completes.
void expect_disk_full_changes_nothing(const fs::path& mnt, const fs::path& site, const fs::path& watched,
                                      const std::vector<std::string>& args) {
  const auto before = test::project_state(site);
  const std::string files_before = test::tree_fingerprint(watched);
  fill_leaving(mnt, kFreeBytesLeft);
  const auto r = run_strata(args);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(r.exit_code, 1) << "a typed error, not a crash: " << r.err;
  const auto at = r.err.rfind("strata: error: ");
  ASSERT_NE(at, std::string::npos) << r.err;
  const std::string error_line = r.err.substr(at);
  EXPECT_EQ(test::line_count(error_line), 1) << r.err;
  EXPECT_NE(error_line.find("No space left on device"), std::string::npos) << r.err;
  EXPECT_NE(error_line.find(site.string()), std::string::npos) << "names the file: " << r.err;
  EXPECT_EQ(test::integrity(site / "project.gpkg"), "ok");
  EXPECT_TRUE(test::project_state(site) == before) << "the failed command recorded something";
  EXPECT_EQ(test::tree_fingerprint(watched), files_before)
      << "a file under " << watched << " was replaced or left behind";

  fs::remove(mnt / "filler");
  const auto again = run_strata(args);
  EXPECT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(test::integrity(site / "project.gpkg"), "ok");
}

TEST_F(Faults, DiskFullDuringProductsRecordsNothing) {
  const fs::path mnt = scratch() / "small_disk";
  Mount disk(mnt);
  if (const std::string why = mount_room_for(disk, shared_ / "template"); !why.empty())
    GTEST_SKIP() << "cannot mount a tmpfs here (" << why << "); the disk-full case needs one";
  const fs::path site = copy_template(mnt / "site");
  // New products (another contour interval): the stage runs, and the disk fills
  // while it writes the DTM.
  expect_disk_full_changes_nothing(mnt, site, site / "products",
                                   {"process", site.string(), "--layer", "L1", "--contour-interval", "0.02"});
}

TEST_F(Faults, DiskFullDuringVolumeRecordsNothing) {
  // Two layers processed and their volume stored, on the ordinary disk (14 photos a
  // layer: with 12, the second layer of this seed aligns only 9).
  const fs::path made = scratch() / "volume_template";
  test::synth(scratch() / "data14", 1, 14, 5);
  test::make_project(made, scratch() / "data14", 2);
  for (const char* layer : {"L1", "L2"}) {
    const auto p = run_strata({"-q", "process", made.string(), "--layer", layer});
    ASSERT_EQ(p.exit_code, 0) << p.err;
  }
  const auto first = run_strata({"-q", "volume", made.string()});
  ASSERT_EQ(first.exit_code, 0) << first.err;

  const fs::path mnt = scratch() / "small_disk_volume";
  Mount disk(mnt);
  if (const std::string why = mount_room_for(disk, made); !why.empty())
    GTEST_SKIP() << "cannot mount a tmpfs here (" << why << "); the disk-full case needs one";
  const fs::path site = mnt / "site";
  fs::copy(made, site, fs::copy_options::recursive);
  // New volumes (another threshold): the disk fills while the voxel model and the
  // thickness rasters are written.
  expect_disk_full_changes_nothing(mnt, site, site / "products" / "volume",
                                   {"volume", site.string(), "--threshold", "0.006"});
}

TEST_F(Faults, ReadOnlyProjectServesReadsAndRefusesWrites) {
  const fs::path site = copy_template(scratch() / "rw_site");
  const fs::path ro = scratch() / "ro_site";
  Mount view(ro);
  if (const std::string why = view.read_only_bind(site); !why.empty())
    GTEST_SKIP() << "cannot make a read-only bind mount here (" << why << "); as root, chmod cannot make a "
                 << "folder read-only, so the case cannot be shown";
  const auto before = test::project_state(site);
  const std::string r_o = ro.string();
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"unit", "add", r_o, "999"},
        std::vector<std::string>{"process", r_o, "--layer", "L1", "--force", "--until", "sparse"},
        std::vector<std::string>{"import", "markers", r_o, (shared_ / "data" / "markers.csv").string(), "--update"}}) {
    const auto r = run_strata(args);
    EXPECT_EQ(r.exit_code, 1) << args[0] << ": " << r.err;
    EXPECT_EQ(test::line_count(r.err), 1) << r.err;
    EXPECT_NE(r.err.find(r_o + ": the project folder cannot be written (Read-only file system)"), std::string::npos)
        << r.err;
  }
  // Reading commands work on read-only media (a DVD, a write-protected card).
  auto r = run_strata({"info", r_o});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  r = run_strata({"markers", r_o});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  r = run_strata({"export", "cameras", r_o, "--layer", "L1", "--out", (scratch() / "ro_cameras.csv").string()});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  r = run_strata({"export", "dtm", r_o, "--layer", "L1", "--out", (scratch() / "ro_dtm.tif").string()});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(test::project_state(site) == before);
}

TEST_F(Faults, MovedProjectKeepsWorking) {
  const fs::path first = copy_template(scratch() / "before_move");
  const fs::path moved = scratch() / "moved" / "trench 7";
  fs::create_directories(moved.parent_path());
  fs::rename(first, moved);
  // No row names the folder the project was processed in.
  const std::string rows = test::database_rows(moved / "project.gpkg");
  EXPECT_EQ(rows.find((shared_ / "template").string()), std::string::npos);
  EXPECT_EQ(rows.find(first.string()), std::string::npos);
  const std::string m = moved.string();
  auto r = run_strata({"info", m, "--json"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find(m), std::string::npos) << "info names the folder where the project is now";
  r = run_strata({"process", m, "--layer", "L1"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("(up to date, not recomputed)"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("products (up to date"), r.out.find("products")) << "products were recomputed: " << r.out;
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"export", "cameras", m, "--layer", "L1", "--out", (scratch() / "mv_cameras.csv").string()},
        std::vector<std::string>{"export", "dtm", m, "--layer", "L1", "--out", (scratch() / "mv_dtm.tif").string()},
        std::vector<std::string>{"report", m, "--layer", "L1", "--out", (scratch() / "mv_report.html").string()}}) {
    r = run_strata(args);
    EXPECT_EQ(r.exit_code, 0) << args[0] << " " << args[1] << ": " << r.err;
  }
}

TEST_F(Faults, AlteredOrMissingPhotoIsNamedAndNotUsed) {
  const fs::path site = copy_template(scratch() / "tampered");
  const std::string s = site.string();
  std::vector<fs::path> photos;
  for (const auto& e : fs::recursive_directory_iterator(site / "media"))
    if (e.is_regular_file()) photos.push_back(e.path());
  std::sort(photos.begin(), photos.end());
  ASSERT_GE(photos.size(), 2u);
  // Photos at rest, as on a site's disk: a file changed within the last seconds is
  // hashed in full every time (the record's racy-clean rule), and the copy just made
  // them all new.
  const auto at_rest = [](const fs::path& p) {
    fs::last_write_time(p, fs::file_time_type::clock::now() - std::chrono::hours(1));
  };
  for (const auto& p : photos) at_rest(p);
  const auto before = test::project_state(site);
  const std::string original = test::read_text(photos[0]);

  // Same size, a few bytes changed (a photo editor's "save" over the original).
  corrupt_middle(photos[0]);
  auto r = run_strata({"process", s, "--layer", "L1", "--force", "--until", "sparse"});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_EQ(test::line_count(r.err), 1) << r.err;
  const std::string rel = fs::relative(photos[0], site).string();
  EXPECT_NE(r.err.find("(" + rel + ") was altered: its SHA-256 is now"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("strata will not use them"), std::string::npos) << r.err;
  EXPECT_EQ(test::database_rows(site / "project.gpkg"), before.rows);

  // Deleted.
  test::write_text(photos[0], original);
  fs::remove(photos[1]);
  r = run_strata({"process", s, "--layer", "L1", "--force", "--until", "sparse"});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("(" + fs::relative(photos[1], site).string() + ") is missing"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find(rel), std::string::npos) << "the restored photo is fine again: " << r.err;
  EXPECT_EQ(test::database_rows(site / "project.gpkg"), before.rows);

  // Put back, the layer is up to date again; photos unchanged since their last
  // check are not read in full.
  fs::copy_file(shared_ / "template" / fs::relative(photos[1], site), photos[1]);
  at_rest(photos[0]);
  at_rest(photos[1]);
  EXPECT_TRUE(test::project_state(site) == before);
  r = run_strata({"process", s, "--layer", "L1"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("(up to date, not recomputed)"), std::string::npos) << r.out;
  r = run_strata({"process", s, "--layer", "L1"});
  EXPECT_NE(r.err.find("photos match their SHA-256 (0 read in full)"), std::string::npos) << r.err;
}

TEST_F(Faults, CorruptCacheFilesAreRecomputedWithAWarning) {
  const fs::path site = copy_template(scratch() / "bad_cache");
  const std::string s = site.string();
  const auto good = run_strata({"export", "cameras", s, "--layer", "L1", "--out", (scratch() / "good.csv").string()});
  ASSERT_EQ(good.exit_code, 0) << good.err;
  int features = 0, matches = 0, dense = 0;
  for (const auto& e : fs::recursive_directory_iterator(site / "cache")) {
    if (!e.is_regular_file()) continue;
    const std::string ext = e.path().extension().string();
    if (ext == ".sift") ++features;
    else if (ext == ".match") ++matches;
    else if (ext == ".dmap" || ext == ".img") ++dense;
    else continue;
    corrupt_middle(e.path());
  }
  ASSERT_GT(features, 0);
  ASSERT_GT(matches, 0);
  ASSERT_GT(dense, 0);
  const auto r = run_strata({"process", s, "--layer", "L1", "--until", "dense", "--force"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("features cache: ignoring corrupt file"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("matches cache: ignoring corrupt file"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("dense.cache: ignoring corrupt file"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("0 from cache"), std::string::npos) << "every feature file was recomputed: " << r.err;
  // Recomputed from the photos, the cameras are those of the undisturbed run.
  const auto again = run_strata({"export", "cameras", s, "--layer", "L1", "--out", (scratch() / "again.csv").string()});
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(test::read_text(scratch() / "again.csv"), test::read_text(scratch() / "good.csv"));
}

}  // namespace
}  // namespace strata
