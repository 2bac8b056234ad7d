// strata import scan through the real CLI: a point cloud registered to the survey
// is stored and summarised; importing it again changes nothing; a truncated file
// is refused in one line naming it and its line, and the project stays as it was.
#include "support/test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>

namespace strata::test {
namespace {

namespace fs = std::filesystem;

int lines(const std::string& s) { return int(std::count(s.begin(), s.end(), '\n')); }

void ok(const CommandResult& r) { ASSERT_EQ(r.exit_code, 0) << r.err; }

TEST(ImportScan, HelpTeachesFormatsRegistrationAndAnExample) {
  const CommandResult r = run_strata({"import", "scan", "--help"});
  EXPECT_EQ(r.exit_code, 0);
  for (const char* want : {"PLY", "PTS", "XYZ", "LAS 1.2-1.4", "E57 and LAZ", "'survey'", "'transform'",
                           "'unregistered'", "--sigma", "Example: strata import scan"})
    EXPECT_NE(r.out.find(want), std::string::npos) << want << " not in:\n" << r.out;
}

TEST(ImportScan, SurveyScanIsImportedOnceAndABadFileChangesNothing) {
  ScratchDir dir("scan");
  const std::string site = (dir / "site").string();
  ok(run_strata({"-q", "init", site, "--crs", "EPSG:32636", "--origin", "734000,4174000,1400"}));
  ok(run_strata({"-q", "unit", "add", site, "101"}));
  ok(run_strata({"-q", "layer", "add", site, "L1", "--unit", "101"}));
  const fs::path xyz = dir / "station1.xyz";
  write_text(xyz, "# x y z r g b\n734010.0 4174020.0 1450.0 10 20 30\n734012.5,4174021.0,1450.5,40,50,60\n"
                  "734011.0 4174023.0 1451.25 70 80 90\n");

  CommandResult r = run_strata({"import", "scan", site, "--layer", "L1", "--crs", "EPSG:32636", "--sigma", "0.004",
                                xyz.string()});
  ok(r);
  EXPECT_NE(r.out.find(xyz.string() + ": 3 points, xyz (with colour), registration survey, 2.50 x 3.00 x 1.25 m "
                                      "in the site frame"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("layer L1: 1 scan(s) imported, 0 already present"), std::string::npos) << r.out;
  r = run_strata({"import", "scan", site, "--layer", "L1", xyz.string()});
  ok(r);
  EXPECT_NE(r.out.find("layer L1: 0 scan(s) imported, 1 already present"), std::string::npos) << r.out;

  // A PTS declaring more points than it holds, after a good file: nothing imported.
  const fs::path good = dir / "station2.xyz", cut = dir / "station3.pts";
  write_text(good, "734010 4174020 1450\n");
  write_text(cut, "4\n734010 4174020 1450 120\n734011 4174020 1450 130\n");
  const std::string tree = tree_fingerprint(dir / "site");
  r = run_strata({"import", "scan", site, "--layer", "L1", good.string(), cut.string()});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("importer.scans.pts: " + cut.string() + ": line 3: the file ends after 2 of the 4 points"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(tree_fingerprint(dir / "site"), tree);
  // A transform that shears: refused naming the file.
  const fs::path shear = dir / "pose.txt";
  write_text(shear, "1 0.1 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
  r = run_strata({"import", "scan", site, "--layer", "L1", "--transform", shear.string(), good.string()});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find(shear.string() + ": not a rigid or similarity transform"), std::string::npos) << r.err;
  EXPECT_EQ(tree_fingerprint(dir / "site"), tree);
}

}  // namespace
}  // namespace strata::test
