// The robust fit of one marker from its rays (georef/marker_rays.hpp), on cameras with
// known truth: exact rays, gross errors, and an object clicked from every side.
#include "core/error.hpp"
#include "georef/marker_rays.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace strata {
namespace {

// --- tolerances ------------------------------------------------------------------
// Exact rays: the fitted point is the true one to numerical precision, metres.
constexpr double kExactTolM = 1e-7;
// 30 rays with 0.3 px click noise at ~0.7 mm per pixel: the point to well under a
// millimetre, metres.
constexpr double kNoisyTolM = 1e-3;
// A dispersion estimated from 30 rays (about 57 degrees of freedom) is good to about
// 1 / sqrt(2 * 57) = 9 % at 1 sigma; 30 % leaves room for the 3-sigma truncation.
constexpr double kDispersionRel = 0.3;

constexpr double kFocalPx = 3000;

// `n` cameras on a ring 2 m out and 1.5 m up around the origin, looking at it: a
// marker photographed from every side, as on a trench edge.
std::vector<Camera> ring(int n) {
  std::vector<Camera> cams;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n;
    Camera c;
    c.intrinsics.width = 4000;
    c.intrinsics.height = 3000;
    c.intrinsics.fx = c.intrinsics.fy = kFocalPx;
    c.intrinsics.cx = 1999.5;
    c.intrinsics.cy = 1499.5;
    c.intrinsics.k1 = -0.05;
    // Aim a little off the marker so it is not always at the principal point.
    c.pose = Pose::look_at({2 * std::cos(a), 2 * std::sin(a), 1.5}, {0.1 * std::sin(3 * a), 0.1, 0});
    cams.push_back(c);
  }
  return cams;
}

std::vector<Eigen::Vector2d> project(const std::vector<Camera>& cams, const Eigen::Vector3d& X) {
  std::vector<Eigen::Vector2d> px;
  for (const auto& c : cams) px.push_back(*c.project(X));
  return px;
}

TEST(MarkerRays, ExactRaysMeetInTheTruePointWithoutDispersion) {
  const auto cams = ring(12);
  const Eigen::Vector3d X(0.02, -0.03, 0.01);
  const auto fit = fit_marker_rays(cams, project(cams, X), {});
  ASSERT_TRUE(fit.ok);
  EXPECT_EQ(fit.agreeing, 12);
  EXPECT_LT((fit.X - X).norm(), kExactTolM);
  EXPECT_EQ(fit.dispersion, 0.0);
  EXPECT_LT(fit.rmse_px, 1e-4);
  EXPECT_GT(fit.max_angle_deg, 90.0);
}

TEST(MarkerRays, HalfTheRaysGrosslyWrongAreFoundAndLeftOut) {
  const auto cams = ring(30);
  const Eigen::Vector3d X(0, 0, 0);
  auto px = project(cams, X);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0, 0.3);
  std::uniform_real_distribution<double> off(20, 180), dir(0, 2 * M_PI);
  std::vector<bool> wrong(px.size(), false);
  for (std::size_t i = 0; i < px.size(); ++i) {
    px[i] += Eigen::Vector2d(noise(rng), noise(rng));
    if (i % 2 == 1 && i < 28) {  // 14 of 30: under half, as least median of squares needs
      const double a = dir(rng), d = off(rng);
      px[i] += d * Eigen::Vector2d(std::cos(a), std::sin(a));
      wrong[i] = true;
    }
  }
  MarkerRayOptions o;
  o.click_sigma_px = 0.3;
  const auto fit = fit_marker_rays(cams, px, o);
  ASSERT_TRUE(fit.ok);
  EXPECT_LT((fit.X - X).norm(), kNoisyTolM);
  int missed = 0, false_alarm = 0;
  for (std::size_t i = 0; i < px.size(); ++i) {
    if (wrong[i] && fit.rays[i].agrees) ++missed;
    if (!wrong[i] && !fit.rays[i].agrees) ++false_alarm;
  }
  EXPECT_EQ(missed, 0) << "every ray 20-180 px off is named";
  EXPECT_EQ(false_alarm, 0) << "no good ray beyond 4 sigma (0.03 % each)";
  EXPECT_LT(fit.dispersion, 0.5e-3) << "the wrong rays do not inflate the dispersion";
}

TEST(MarkerRays, AnObjectClickedFromEverySideGetsItsDispersion) {
  // The clicks land on a point of the object that depends on the view: 3 cm per axis
  // about its centre (a 10 cm object, 36 px per sigma at 2.5 m), plus 0.5 px of click
  // noise; 6 of 30 were placed by another program 250-500 px off (beyond 6 sigma: what
  // lies within 3 sigma of the scatter cannot be told from it, and is weighed with it).
  const auto cams = ring(30);
  constexpr double kSpreadM = 0.03;
  std::mt19937 rng(11);
  std::normal_distribution<double> spread(0, kSpreadM), click(0, 0.5);
  std::uniform_real_distribution<double> off(250, 500), dir(0, 2 * M_PI);
  std::vector<Eigen::Vector2d> px;
  std::vector<bool> wrong;
  for (std::size_t i = 0; i < cams.size(); ++i) {
    const Eigen::Vector3d seen(spread(rng), spread(rng), spread(rng));
    Eigen::Vector2d p = *cams[i].project(seen) + Eigen::Vector2d(click(rng), click(rng));
    const bool w = i % 5 == 2;
    if (w) {
      const double a = dir(rng);
      p += off(rng) * Eigen::Vector2d(std::cos(a), std::sin(a));
    }
    px.push_back(p);
    wrong.push_back(w);
  }
  MarkerRayOptions o;
  o.click_sigma_px = 0.5;
  const auto fit = fit_marker_rays(cams, px, o);
  ASSERT_TRUE(fit.ok);
  // The spread seen across a ray is 2 of the 3 axes: its per-axis sigma is kSpreadM.
  std::printf("[ figures  ] object marker: dispersion %.1f mm (truth %.1f), %d of 30 agree, point %.1f mm off\n",
              fit.dispersion * 1e3, kSpreadM * 1e3, fit.agreeing, fit.X.norm() * 1e3);
  EXPECT_NEAR(fit.dispersion, kSpreadM, kDispersionRel * kSpreadM);
  // The centre of 24 scattered clicks: about 3 cm / sqrt(24) per axis.
  EXPECT_LT(fit.X.norm(), 3 * kSpreadM / std::sqrt(24.0) * std::sqrt(3.0));
  int named = 0;
  for (std::size_t i = 0; i < px.size(); ++i) named += wrong[i] && !fit.rays[i].agrees;
  EXPECT_EQ(named, 6) << "the positions 250-500 px off are named";
  // 24 scattered clicks: beyond 4 sigma of the true centre 0.03 % each; the fitted
  // centre is itself off by about 0.6 sigma, which may push one out.
  EXPECT_GE(fit.agreeing, 23);
}

TEST(MarkerRays, RaysOnDifferentObjectsAreNotOnePoint) {
  // Two groups of clicks 1.2 m apart (the same name given to two markers).
  const auto cams = ring(10);
  std::vector<Eigen::Vector2d> px;
  for (std::size_t i = 0; i < cams.size(); ++i) {
    px.push_back(*cams[i].project(i % 2 ? Eigen::Vector3d(0.6, 0, 0) : Eigen::Vector3d(-0.6, 0.1, 0)));
  }
  const auto fit = fit_marker_rays(cams, px, {});
  // One of the two points with its half of the rays, never a point between them
  // accepted with all ten.
  EXPECT_EQ(fit.agreeing, 5);
  EXPECT_LT(fit.dispersion, 1e-6);
}

TEST(MarkerRays, OptionsAreValidated) {
  MarkerRayOptions o;
  o.agree_factor = 1.0;
  EXPECT_THROW(o.validate(), InputError);
  o = {};
  o.click_sigma_px = 0;
  EXPECT_THROW(o.validate(), InputError);
}

TEST(MarkerRays, TwoRaysGiveAPointThreeRaysNameTheWrongOne) {
  const auto cams = ring(3);
  const Eigen::Vector3d X(0, 0, 0.02);
  auto px = project(cams, X);
  const auto two = fit_marker_rays({cams[0], cams[1]}, {px[0], px[1]}, {});
  ASSERT_TRUE(two.ok);
  EXPECT_LT((two.X - X).norm(), kExactTolM);
  px[2] += Eigen::Vector2d(40, 0);
  const auto three = fit_marker_rays(cams, px, {});
  ASSERT_TRUE(three.ok);
  EXPECT_EQ(three.agreeing, 2);
  EXPECT_FALSE(three.rays[2].agrees);
}

}  // namespace
}  // namespace strata
