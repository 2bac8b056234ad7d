// The checks at the door (core/door.hpp, docs/reliability.md), through the real
// `strata` executable: every kind of hostile value is refused in one line naming it,
// and the project (database and media) is left exactly as it was.
#include "support/test_support.hpp"

#include <fmt/format.h>
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <ogr_spatialref.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <functional>
#include <sstream>
#include <thread>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::run_strata;

constexpr double kWest = 734000, kNorth = 4174020;  // the test rasters' north-west corner (EPSG:32636)

// A 2 x 2 m height raster at 1 cm, `z` and `z_middle` in its middle metre.
void write_surface(const fs::path& path, double z, double z_middle, int epsg = 32636) {
  GDALAllRegister();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  GDALDataset* ds = driver->Create(path.c_str(), 200, 200, 1, GDT_Float32, nullptr);
  double gt[6] = {kWest, 0.01, 0, kNorth, 0, -0.01};
  ds->SetGeoTransform(gt);
  OGRSpatialReference srs;
  srs.importFromEPSG(epsg);
  ds->SetSpatialRef(&srs);
  std::vector<float> v(200 * 200, float(z));
  for (int r = 50; r < 150; ++r)
    for (int c = 50; c < 150; ++c) v[std::size_t(r) * 200 + std::size_t(c)] = float(z_middle);
  EXPECT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, 200, 200, v.data(), 200, 200, GDT_Float32, 0, 0), CE_None);
  GDALClose(ds);
}

std::string polygon_geojson(const std::vector<std::pair<double, double>>& ring, const std::string& crs = "") {
  std::string coords;
  for (const auto& [x, y] : ring) coords += fmt::format("{}[{}, {}]", coords.empty() ? "" : ", ", x, y);
  const std::string crs_member =
      crs.empty() ? "" : fmt::format(R"("crs": {{"type": "name", "properties": {{"name": "{}"}}}}, )", crs);
  return fmt::format(R"({{"type": "FeatureCollection", {}"features": [{{"type": "Feature", "properties": {{}}, )"
                     R"("geometry": {{"type": "Polygon", "coordinates": [[{}]]}}}}]}})",
                     crs_member, coords);
}

int lines(const std::string& s) { return int(std::count(s.begin(), s.end(), '\n')); }

// A project of two layers on units 101 above 102, with their surfaces as GeoTIFFs
// beside it, and the hostile files of the tests.
class Door : public ::testing::Test {
 protected:
  void SetUp() override {
    site = (dir / "site").string();
    ASSERT_EQ(run_strata({"init", site, "--crs", "EPSG:32636"}).exit_code, 0);
    for (const auto& args : std::vector<std::vector<std::string>>{{"unit", "add", site, "101"},
                                                                   {"unit", "add", site, "102"},
                                                                   {"relation", "add", site, "101", "above", "102"},
                                                                   {"layer", "add", site, "L1", "--unit", "101"},
                                                                   {"layer", "add", site, "L2", "--unit", "102"}}) {
      const auto r = run_strata(args);
      ASSERT_EQ(r.exit_code, 0) << r.err;
    }
    // Unit 101 is the middle metre, 0.1 m deep: 0.1 m3; the ground around is stable.
    write_surface(dir / "top.tif", 100.0, 100.0);
    write_surface(dir / "bottom.tif", 100.0, 99.9);
    surfaces = {"--surface", "L1=" + (dir / "top.tif").string(), "--surface", "L2=" + (dir / "bottom.tif").string()};
  }

  // The project's files, byte for byte (the lock file's holder line aside).
  std::string fingerprint() const {
    std::string f;
    std::istringstream lines_of(test::tree_fingerprint(site));
    for (std::string line; std::getline(lines_of, line);)
      if (line.rfind("project.lock", 0) != 0) f += line + "\n";
    return f;
  }

  // `args` fails with exit status 1, one line on stderr holding every one of
  // `expected`, and the project unchanged.
  void refused(const std::vector<std::string>& args, const std::vector<std::string>& expected) {
    const std::string before = fingerprint();
    const auto r = run_strata(args);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    // One line says why (progress lines of the steps before it may precede it).
    const auto last = r.err.rfind('\n', r.err.size() >= 2 ? r.err.size() - 2 : 0);
    const std::string refusal = last == std::string::npos ? r.err : r.err.substr(last + 1);
    EXPECT_EQ(refusal.rfind("strata: error: ", 0), 0u) << r.err;
    EXPECT_EQ(lines(refusal), 1) << r.err;
    EXPECT_EQ(r.err.find("strata: error: "), r.err.rfind("strata: error: ")) << r.err;
    for (const auto& e : expected) EXPECT_NE(r.err.find(e), std::string::npos) << "'" << e << "' not in: " << r.err;
    EXPECT_EQ(fingerprint(), before) << "the refused command changed the project";
  }

  std::vector<std::string> with(std::vector<std::string> head, const std::vector<std::string>& tail) const {
    head.insert(head.end(), tail.begin(), tail.end());
    return head;
  }

  test::ScratchDir dir{"door"};
  std::string site;
  std::vector<std::string> surfaces;
};

TEST_F(Door, PathsThatAreNotRegularFilesAreNamed) {
  const fs::path fifo = dir / "survey.csv";
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  fs::create_symlink("loop_b", dir / "loop_a");
  fs::create_symlink("loop_a", dir / "loop_b");
  fs::create_symlink("nowhere.geojson", dir / "dangling.geojson");
  // A named pipe would wait for a writer forever (and hold the lock meanwhile).
  refused({"import", "finds", site, fifo.string()}, {"finds CSV", "survey.csv", "named pipe"});
  refused({"import", "markers", site, fifo.string()}, {"survey.csv", "named pipe"});
  refused({"import", "units", site, "/dev/zero"}, {"/dev/zero", "device"});
  refused({"import", "markers", site, (dir / "loop_a").string()}, {"loop_a", "loop of symbolic links"});
  refused(with({"volume", site, "--outline", (dir / "dangling.geojson").string()}, surfaces),
          {"--outline", "dangling.geojson", "symbolic link to 'nowhere.geojson', which does not exist"});
  refused({"volume", site, "--surface", "L1=" + (dir / "loop_b").string()}, {"--surface of L1", "loop"});
  refused({"import", "photos", site, "--layer", "L1", dir.path().string()}, {"is a folder"});
  const auto info = run_strata({"info", (dir / "loop_a").string()});
  EXPECT_EQ(info.exit_code, 1);
  EXPECT_NE(info.err.find("project folder"), std::string::npos) << info.err;
  // Where strata writes: a named pipe there would block the writer.
  const fs::path out_fifo = dir / "section.svg";
  ASSERT_EQ(mkfifo(out_fifo.c_str(), 0600), 0);
  refused(with({"export", "section", site, "--line", "734000.2,4174019,734001.8,4174019", "--out", out_fifo.string()},
               surfaces),
          {"--out", "section.svg", "named pipe"});
}

TEST_F(Door, NumbersAreBoundedBeforeAnythingIsAllocated) {
  // A section line of 10^10 m (an integer overflow, then a segfault, before).
  refused(with({"export", "section", site, "--line", "734000.2,4174019,1e10,4174019", "--out", (dir / "s.svg").string()},
               surfaces),
          {"second end", "10000000000", "not a coordinate"});
  // A step of 10^-9 m (std::bad_alloc, or the kernel's OOM killer, before).
  refused(with({"export", "section", site, "--line", "734000.2,4174019,734001.8,4174019", "--step", "1e-9", "--out",
                (dir / "s.svg").string()},
               surfaces),
          {"sampled every 1e-09 m", "GB", "--step"});
  // A raster whose header claims 10^6 x 10^6 pixels (a VRT: the header without the pixels).
  test::write_text(dir / "huge.vrt",
                   R"(<VRTDataset rasterXSize="1000000" rasterYSize="1000000"><SRS>EPSG:32636</SRS>)"
                   R"(<GeoTransform>734000, 0.01, 0, 4174020, 0, -0.01</GeoTransform>)"
                   R"(<VRTRasterBand dataType="Float32" band="1"></VRTRasterBand></VRTDataset>)");
  refused({"volume", site, "--surface", "L1=" + (dir / "top.tif").string(), "--surface",
           "L2=" + (dir / "huge.vrt").string()},
          {"huge.vrt", "1000000 x 1000000 pixels", "GB"});
  // Coordinates of 1e308 for a find; a find 100 km underground; a marker 660 km away.
  refused({"find", "add", site, "--id", "F1", "--at", "1e308,1e308,1e308", "--unit", "101"},
          {"find 'F1'", "not a coordinate in the site CRS"});
  refused({"find", "add", site, "--id", "F1", "--at", "734001,4174019,-100000", "--unit", "101"}, {"height"});
  test::write_text(dir / "survey.csv", "name,E,N,Z\nA,734000,4174000,100\nB,73400,4174000,100\n");
  refused({"import", "markers", site, (dir / "survey.csv").string()}, {"survey.csv:3", "marker 'B'", "km from"});
  // A point outside the CRS's area of use (UTM 36N used 90 degrees away).
  refused({"find", "add", site, "--id", "F2", "--at", "9000000,4174019,100", "--unit", "101"}, {"area", "EPSG:32636"});
  refused(with({"export", "section", site, "--line", "734000.2,4174019,734001.8,4174019", "--finds-within", "1e300",
                "--out", (dir / "s.svg").string()},
               surfaces),
          {"--finds-within"});
}

TEST_F(Door, CodesAndNamesArePrintableTrimmedAndInOneNormalForm) {
  refused({"unit", "add", site, ""}, {"code is empty"});
  refused({"unit", "add", site, "   "}, {"code is empty"});
  refused({"unit", "add", site, "1\x01" "03"}, {"control character", "U+0001"});
  refused({"unit", "add", site, "1\xe2\x80\x8b" "03"}, {"invisible format character", "U+200B"});
  refused({"unit", "add", site, "\xff\xfe"}, {"not UTF-8"});
  refused({"unit", "add", site, std::string(65, '7')}, {"65 characters long, more than 64"});
  refused({"layer", "add", site, "", "--unit", "101"}, {"name is empty"});
  // One code typed on two keyboards is one unit: e + combining acute is é.
  const auto composed = run_strata({"unit", "add", site, "  \xc3\xa9 ", "--type", "cut"});
  ASSERT_EQ(composed.exit_code, 0) << composed.err;
  refused({"unit", "add", site, "e\xcc\x81"}, {"unit '\xc3\xa9' already exists"});
  // The register's codes pass the same door, with the file and line.
  test::write_text(dir / "units.csv", "code,type\n201,deposit\n2\x07" "02,deposit\n");
  refused({"import", "units", site, (dir / "units.csv").string()}, {"units.csv:3", "control character"});
  test::write_text(dir / "finds.csv", "id,E,N,Z,unit\nF\xe2\x80\xae" "1,734001,4174019,99.95,101\n");
  refused({"import", "finds", site, (dir / "finds.csv").string()}, {"finds.csv:2", "U+202E"});
  // Quotes and backslashes are printable, so allowed; the DOT text escapes them.
  ASSERT_EQ(run_strata({"unit", "add", site, "a\"b\\c"}).exit_code, 0);
  const auto dot = run_strata({"matrix", site, "--format", "dot"});
  ASSERT_EQ(dot.exit_code, 0) << dot.err;
  EXPECT_NE(dot.out.find("[label=\"a\\\"b\\\\c\"]"), std::string::npos) << dot.out;
  EXPECT_TRUE(std::none_of(dot.out.begin(), dot.out.end(), [](char c) { return c > 0 && c < 0x20 && c != '\n' && c != '\t'; }));
}

TEST_F(Door, DatesExistInTheCalendar) {
  refused({"layer", "add", site, "L9", "--unit", "101", "--captured-at", "2026-13-45"}, {"there is no month 13"});
  refused({"layer", "add", site, "L9", "--unit", "101", "--captured-at", "2025-02-29"}, {"month 2 of 2025 has no day 29"});
  refused({"layer", "add", site, "L9", "--unit", "101", "--captured-at", "2026-05-14T25:00"}, {"not a time of day"});
  refused({"layer", "add", site, "L9", "--unit", "101", "--captured-at", "1700-05-14"}, {"1839"});
  refused({"layer", "add", site, "L9", "--unit", "101", "--captured-at", "14/05/2026"}, {"not an ISO 8601 date"});
  const auto leap = run_strata({"layer", "add", site, "L9", "--unit", "101", "--captured-at", "2024-02-29T09:31:02+03:00"});
  EXPECT_EQ(leap.exit_code, 0) << leap.err;
}

TEST_F(Door, GeometriesAreValidAndInTheSiteCrs) {
  const fs::path kept = fs::path(site) / "trench_outline.geojson";
  // Refusals first: each leaves no kept outline behind.
  test::write_text(dir / "far.geojson", polygon_geojson({{34.0, 37.0}, {34.001, 37.0}, {34.001, 37.001}, {34.0, 37.0}},
                                                        "urn:ogc:def:crs:OGC:1.3:CRS84"));
  refused(with({"volume", site, "--outline", (dir / "far.geojson").string()}, surfaces),
          {"--outline", "does not overlap the site's surfaces", "another CRS"});
  test::write_text(dir / "line.geojson", polygon_geojson({{kWest + 0.2, kNorth - 1.8}, {kWest + 1, kNorth - 1},
                                                          {kWest + 1.8, kNorth - 0.2}, {kWest + 0.2, kNorth - 1.8}}));
  refused(with({"volume", site, "--outline", (dir / "line.geojson").string()}, surfaces), {"encloses no area"});
  test::write_text(dir / "bowtie.geojson",
                   polygon_geojson({{kWest + 0.2, kNorth - 1.8}, {kWest + 1.8, kNorth - 0.2}, {kWest + 1.8, kNorth - 1.8},
                                    {kWest + 0.2, kNorth - 0.2}, {kWest + 0.2, kNorth - 1.8}}));
  refused(with({"volume", site, "--outline", (dir / "bowtie.geojson").string()}, surfaces),
          {"crosses itself", "edge 1-2 meets edge 3-4", "734001.000, 4174019.000"});
  refused(with({"volume", site, "--footprint", "999=" + (dir / "bowtie.geojson").string()}, surfaces),
          {"--footprint names unit '999'", "not in the project"});
  write_surface(dir / "zone35.tif", 100.0, 99.9, 32635);  // the same numbers in the next UTM zone: 530 km west
  refused({"volume", site, "--surface", "L1=" + (dir / "top.tif").string(), "--surface",
           "L2=" + (dir / "zone35.tif").string()},
          {"overlaps no other layer's surface", "zone35.tif", "another CRS"});
  EXPECT_FALSE(fs::exists(kept));
  // An outline in longitude and latitude (CRS84) around the middle metre: transformed
  // into the site CRS and used. The volume is the 1 m2 x 0.1 m dug in the middle.
  GDALAllRegister();
  OGRSpatialReference utm, ll;
  utm.importFromEPSG(32636);
  ll.importFromEPSG(4326);
  utm.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  ll.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> to_ll(OGRCreateCoordinateTransformation(&utm, &ll));
  std::vector<std::pair<double, double>> ring;
  for (const auto& [e, n] : std::vector<std::pair<double, double>>{
           {kWest + 0.3, kNorth - 1.7}, {kWest + 1.7, kNorth - 1.7}, {kWest + 1.7, kNorth - 0.3}, {kWest + 0.3, kNorth - 0.3},
           {kWest + 0.3, kNorth - 1.7}}) {
    double x = e, y = n;
    ASSERT_TRUE(to_ll->Transform(1, &x, &y));
    ring.emplace_back(x, y);
  }
  test::write_text(dir / "lonlat.geojson", polygon_geojson(ring, "urn:ogc:def:crs:OGC:1.3:CRS84"));
  const auto r = run_strata(with({"volume", site, "--json", "--outline", (dir / "lonlat.geojson").string()}, surfaces));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("transformed from WGS 84 into the site CRS EPSG:32636"), std::string::npos) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j.size(), 1u);
  EXPECT_NEAR(j[0]["volume_m3"].get<double>(), 0.1, 0.01) << r.out;
  // The kept outline names its CRS, so that a later run reads it in the site CRS.
  ASSERT_TRUE(fs::exists(kept));
  EXPECT_NE(test::read_text(kept).find("urn:ogc:def:crs:EPSG::32636"), std::string::npos);
  const auto again = run_strata(with({"volume", site, "--json"}, surfaces));
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_NEAR(nlohmann::json::parse(again.out)[0]["volume_m3"].get<double>(), 0.1, 0.01);
}

// Runs strata in the background with `env` set; its stderr goes to `err`.
pid_t start_strata(const std::vector<std::string>& args, const std::vector<std::string>& env, const fs::path& err) {
  const std::string exe = test::strata_exe().string();
  const pid_t pid = fork();
  if (pid == 0) {
    for (const auto& e : env) putenv(const_cast<char*>(e.c_str()));
    const int fd = open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    dup2(fd, 2);
    std::vector<char*> argv{const_cast<char*>(exe.c_str())};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(exe.c_str(), argv.data());
    _exit(127);
  }
  return pid;
}

// The exit status of `pid`, or -1 when it is still running after `seconds`.
int wait_for(pid_t pid, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return -1;
}

bool wait_until(const std::function<bool()>& condition, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    if (condition()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return false;
}

TEST_F(Door, ASignalEndsACommandStuckAwayFromASafePointAndReleasesTheLock) {
  // The unit's row is inserted, and the command hangs before its commit without ever
  // checking for cancellation (as one stuck in a system call would).
  const std::string before = fingerprint();
  const fs::path err = dir / "stderr.txt";
  const pid_t pid = start_strata({"unit", "add", site, "103"},
                                 {"STRATA_STALL_AT=stratigraphy.unit_before_commit", "STRATA_STOP_GRACE_S=1"}, err);
  // The lock's file names its holder once it is taken.
  ASSERT_TRUE(wait_until([&] { return test::read_text(fs::path(site) / "project.lock").find("unit add 103") != std::string::npos; }, 30))
      << "the stalled command never took the lock";
  const auto busy = run_strata({"unit", "add", site, "104"});
  EXPECT_NE(busy.err.find("project is busy"), std::string::npos) << busy.err;
  kill(pid, SIGTERM);
  const int status = wait_for(pid, 20);
  if (status == -1) kill(pid, SIGKILL);
  ASSERT_EQ(status, 130) << test::read_text(err);
  EXPECT_NE(test::read_text(err).find("no safe point reached within 1 s"), std::string::npos) << test::read_text(err);
  // The lock is free at once and the interrupted unit was never recorded.
  const auto next = run_strata({"unit", "add", site, "104"});
  EXPECT_EQ(next.exit_code, 0) << next.err;
  const auto info = run_strata({"info", site, "--json"});
  ASSERT_EQ(info.exit_code, 0) << info.err;
  EXPECT_EQ(info.out.find("\"103\""), std::string::npos);
  EXPECT_NE(before, fingerprint());  // 104 is in
}

TEST_F(Door, ASecondSignalStopsAtOnceAndRemovesTheTemporaryFiles) {
  const fs::path out = dir / "site.qgs", temporary = dir / "site.tmp.qgs", err = dir / "stderr.txt";
  const pid_t pid = start_strata({"export", "qgis", site, "--out", out.string()},
                                 {"STRATA_STALL_AT=export.qgis.temp_written", "STRATA_STOP_GRACE_S=600"}, err);
  ASSERT_TRUE(wait_until([&] { return fs::exists(temporary); }, 30)) << test::read_text(err);
  kill(pid, SIGINT);
  EXPECT_EQ(wait_for(pid, 1), -1) << "the first signal waits for a safe point";
  kill(pid, SIGINT);
  const int status = wait_for(pid, 10);
  if (status == -1) kill(pid, SIGKILL);
  EXPECT_EQ(status, 130) << test::read_text(err);
  EXPECT_FALSE(fs::exists(temporary)) << "the stop left the temporary file";
  EXPECT_FALSE(fs::exists(out));
  EXPECT_NE(test::read_text(err).find("1 temporary file(s) removed"), std::string::npos) << test::read_text(err);
}

}  // namespace
}  // namespace strata
