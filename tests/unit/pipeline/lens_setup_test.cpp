// The lens policy of the alignment: which model a camera gets, and the focal search
// for photos without EXIF (with a stand-in for the reconstruction, so the rules are
// tested on their own, in milliseconds).
#include "core/error.hpp"
#include "pipeline/lens_setup.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace strata {
namespace {

CameraRecord camera(const std::string& make, const std::string& model, std::optional<double> f35) {
  CameraRecord c;
  c.make = make;
  c.model = model;
  c.width = 4000;
  c.height = 3000;
  c.focal_35mm = f35;
  return c;
}

TEST(LensChoice, ByEquivalentFocalLength) {
  const LensChoiceOptions o;
  EXPECT_EQ(choose_lens_model(o, camera("X", "Y", 16.0)).model, CameraModel::fisheye);
  EXPECT_EQ(choose_lens_model(o, camera("X", "Y", 19.9)).model, CameraModel::fisheye);
  EXPECT_EQ(choose_lens_model(o, camera("X", "Y", 20.0)).model, CameraModel::brown);
  EXPECT_EQ(choose_lens_model(o, camera("X", "Y", 26.0)).model, CameraModel::brown);
  EXPECT_EQ(choose_lens_model(o, camera("X", "Y", 28.0)).model, CameraModel::radial);
  EXPECT_EQ(choose_lens_model(o, camera("X", "Y", 50.0)).model, CameraModel::radial);
  EXPECT_EQ(choose_lens_model(o, camera("X", "Y", 26.0)).source, "focal_35mm");
}

TEST(LensChoice, FromThePixelFocalWithoutA35mmTag) {
  CameraRecord c = camera("X", "Y", std::nullopt);
  c.focal_px = 2000;  // over a 4000 px long side: 18 mm equivalent
  const LensChoice l = choose_lens_model({}, c);
  ASSERT_TRUE(l.focal_35mm.has_value());
  EXPECT_NEAR(*l.focal_35mm, 18.0, 1e-12);
  EXPECT_EQ(l.model, CameraModel::fisheye);
}

TEST(LensChoice, FisheyeWordOptionAndNothingKnown) {
  const LensChoiceOptions o;
  EXPECT_EQ(choose_lens_model(o, camera("GoPro", "HERO9 Black", 50.0)).model, CameraModel::fisheye);
  EXPECT_EQ(choose_lens_model(o, camera("GoPro", "HERO9 Black", 50.0)).source, "lens_name");
  LensChoiceOptions brown;
  brown.model = "brown";
  EXPECT_EQ(choose_lens_model(brown, camera("GoPro", "HERO9", 15.0)).model, CameraModel::brown);
  EXPECT_EQ(choose_lens_model(brown, std::nullopt).source, "option");
  const LensChoice none = choose_lens_model(o, std::nullopt);
  EXPECT_EQ(none.model, CameraModel::radial);
  EXPECT_EQ(none.source, "default");
  LensChoiceOptions bad;
  bad.model = "pinhole";
  EXPECT_THROW(bad.validate(), InputError);
}

TEST(LensChoice, AKnownCalibrationKeepsItsModel) {
  CameraGroup g;
  g.intrinsics.model = CameraModel::brown;
  g.calibration_known = true;
  g.calibration_source = "camera set";
  LensChoice c = choose_lens_model({}, camera("X", "Y", 16.0));  // would be fisheye
  apply_lens_choice(g, c);
  EXPECT_EQ(g.intrinsics.model, CameraModel::brown);
  EXPECT_EQ(c.model, CameraModel::brown);
  EXPECT_EQ(c.source, "calibration");
}

// A stand-in for the incremental reconstruction: registers every photo when the
// prior is within 25 % of the true focal, half of them otherwise, none beyond twice
// the truth (a ProcessingError), and "finds" the
// truth when it succeeds.
constexpr double kTrueFocalPx = 2760;
constexpr std::size_t kPhotos = 8;

Reconstruction fake_reconstruct(const std::vector<CameraGroup>& groups, IncrementalSummary& s,
                                std::vector<double>& priors_seen) {
  const double prior = groups[0].intrinsics.fx;
  priors_seen.push_back(prior);
  if (prior > 2 * kTrueFocalPx) throw ProcessingError("no initial pair");
  const bool good = std::abs(prior / kTrueFocalPx - 1) < 0.25;
  s.images = kPhotos;
  s.registered = good ? kPhotos : kPhotos / 2;
  s.reprojection_rmse_px = good ? 0.4 : 2.5;
  Reconstruction rec;
  rec.groups = groups;
  rec.groups[0].intrinsics.fx = rec.groups[0].intrinsics.fy = good ? kTrueFocalPx : prior;
  return rec;
}

std::vector<CameraGroup> no_exif_group(int width, int height) {
  CameraGroup g;
  g.intrinsics.width = width;
  g.intrinsics.height = height;
  g.intrinsics.fx = g.intrinsics.fy = 1.2 * std::max(width, height);
  return {g};
}

TEST(FocalSearch, TriesOtherPriorsWhenTheDefaultFailsAndKeepsTheBest) {
  // 1.2 x 3072 = 3686 px is 34 % long: poor; 0.8 x = 2458 (11 % short) is good.
  std::vector<double> seen;
  IncrementalSummary best;
  FocalSearchSummary summary;
  const Reconstruction rec = reconstruct_with_focal_search(
      {}, no_exif_group(3072, 2048),
      [&](const std::vector<CameraGroup>& g, IncrementalSummary& s) { return fake_reconstruct(g, s, seen); },
      best, summary);
  ASSERT_EQ(summary.attempts.size(), 4u);  // every prior once
  EXPECT_NEAR(seen[0], 1.2 * 3072, 1e-9);
  EXPECT_NEAR(seen[1], 0.8 * 3072, 1e-9);
  EXPECT_EQ(summary.groups, std::vector<int>{0});
  EXPECT_TRUE(summary.attempts[1].chosen);
  EXPECT_FALSE(summary.attempts[0].chosen);
  EXPECT_EQ(best.registered, kPhotos);
  EXPECT_EQ(rec.groups[0].intrinsics.fx, kTrueFocalPx);
  // The 2.2 x prior (6758 px) fails outright: listed with its reason.
  EXPECT_FALSE(summary.attempts[3].failure.empty());
  EXPECT_TRUE(std::isinf(summary.attempts[3].rmse_px));
}

TEST(FocalSearch, AGoodFirstAttemptIsKept) {
  std::vector<double> seen;
  IncrementalSummary best;
  FocalSearchSummary summary;
  // 1.2 x 2400 = 2880 px, 4 % from the truth.
  reconstruct_with_focal_search(
      {}, no_exif_group(2400, 1600),
      [&](const std::vector<CameraGroup>& g, IncrementalSummary& s) { return fake_reconstruct(g, s, seen); },
      best, summary);
  ASSERT_EQ(summary.attempts.size(), 1u);
  EXPECT_TRUE(summary.attempts[0].chosen);
}

TEST(FocalSearch, GroupsWithAFocalAreNotSearched) {
  std::vector<CameraGroup> groups = no_exif_group(3072, 2048);
  groups[0].focal_from_exif = true;
  std::vector<double> seen;
  IncrementalSummary best;
  FocalSearchSummary summary;
  reconstruct_with_focal_search(
      {}, groups,
      [&](const std::vector<CameraGroup>& g, IncrementalSummary& s) { return fake_reconstruct(g, s, seen); },
      best, summary);
  EXPECT_TRUE(summary.groups.empty());
  EXPECT_EQ(seen.size(), 1u);  // one run, the prior untouched
}

}  // namespace
}  // namespace strata
