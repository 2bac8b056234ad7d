#pragma once
// The door for coordinates (docs/reliability.md, "Checks at the door"): a surveyed
// point handed to strata (a find, a marker, a section line's end) must be a place on
// the Earth where the site CRS is meant to be used, near the site. 1e308 for a find,
// a survey typed in the wrong zone or with a digit missing is refused here, naming the
// value, before it is stored or sized into a grid.
#include "project/project.hpp"

#include <Eigen/Core>

#include <string_view>

namespace strata {

// How far from the site's origin a point of the site may be, horizontally: larger
// than any excavation, small enough to catch a misplaced digit.
inline constexpr double kSiteRadius_m = 20'000;
// Heights on the Earth: the deepest mine to above the highest summit.
inline constexpr double kLowestZ_m = -12'000, kHighestZ_m = 9'000;
// How far outside its CRS's stated area of use a site may lie (sites near a UTM
// zone's edge are commonly surveyed in the neighbouring zone).
inline constexpr double kAreaOfUseMargin_deg = 3;

// Refuses with InputError "<what>: E, N, Z ..." a point in the site CRS that is not
// finite, has a height off the Earth, lies outside the site CRS's area of use (plus
// the margin), or further than kSiteRadius_m from the site's origin once it is set.
void check_site_point(const SiteInfo& site, const Eigen::Vector3d& point, std::string_view what);
// The same for a plan position (E, N) without a height.
void check_site_position(const SiteInfo& site, const Eigen::Vector2d& position, std::string_view what);

}  // namespace strata
