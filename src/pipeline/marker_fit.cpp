#include "pipeline/marker_fit.hpp"

#include "core/error.hpp"
#include "geometry/similarity.hpp"
#include "project/records.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

namespace strata {
namespace {

// First-order pose sigmas of a fit on `points` (site frame) with residual RMS `rms`.
std::pair<double, double> pose_sigmas(const std::vector<Eigen::Vector3d>& points, double rms) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : points) c += p;
  c /= double(points.size());
  double spread2 = 0;
  for (const auto& p : points) spread2 += (p - c).squaredNorm();
  return {rms / std::sqrt(double(points.size())), spread2 > 0 ? rms / std::sqrt(spread2) : INFINITY};
}

}  // namespace

MarkerPairs pair_with_markers(Project& project, const std::vector<NamedPoint>& points) {
  std::map<std::string, MarkerRecord> markers;
  for (MarkerRecord& m : list_markers(project.db())) markers.emplace(m.name, std::move(m));
  const Eigen::Vector3d origin = project.site().origin;
  MarkerPairs out;
  for (const NamedPoint& t : points) {
    const auto it = markers.find(t.name);
    if (it == markers.end()) {
      out.unmatched.push_back(t.name);
      continue;
    }
    out.names.push_back(t.name);
    out.local.push_back(t.local);
    out.site.push_back(it->second.position - origin);
    out.largest_marker_sigma_m = std::max(out.largest_marker_sigma_m, it->second.sigma.norm());
  }
  return out;
}

MarkerFit fit_on_markers(const MarkerPairs& pairs, const MarkerFitOptions& options, const std::string& subject,
                         const std::string& source) {
  STRATA_CHECK(pairs.names.size() >= 3, "{} pairs", pairs.names.size());
  MarkerFit r;
  r.gate_m = std::max(options.min_gate_m,
                      options.gate_sigmas * std::hypot(options.point_sigma_m, pairs.largest_marker_sigma_m));
  RobustSimilarity fit;
  try {
    fit = fit_similarity_robust(pairs.local, pairs.site, r.gate_m);
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: cannot register it on {}: {}. Nothing was changed", subject, source, e.what()));
  }
  if (std::abs(fit.fit.scale - 1) > options.max_scale_error)
    throw InputError(fmt::format("{}: {} fit with a scale of {:.5f}, not 1 within {}: their coordinates are not in "
                                 "metres, or names are mismatched. Nothing was changed",
                                 subject, source, fit.fit.scale, options.max_scale_error));
  // The instrument measures in metres: the pose is the rigid motion fitted to the
  // inliers (a free scale would only absorb their noise); the similarity's scale stays
  // a check.
  std::vector<Eigen::Vector3d> inlier_local, inlier_site;
  for (std::size_t i = 0; i < pairs.names.size(); ++i) {
    if (!fit.inlier[i]) continue;
    inlier_local.push_back(pairs.local[i]);
    inlier_site.push_back(pairs.site[i]);
  }
  const Similarity3 rigid = fit_rigid(inlier_local, inlier_site);
  double sum2 = 0;
  for (std::size_t i = 0; i < pairs.names.size(); ++i) {
    const double residual = (rigid.apply(pairs.local[i]) - pairs.site[i]).norm();
    r.targets.push_back({pairs.names[i], residual, bool(fit.inlier[i])});
    if (fit.inlier[i]) sum2 += residual * residual;
  }
  r.scale = fit.fit.scale;
  r.inliers = fit.inliers;
  r.rms_m = std::sqrt(sum2 / double(r.inliers));
  std::tie(r.sigma_translation_m, r.sigma_rotation_rad) = pose_sigmas(inlier_site, r.rms_m);
  r.pose.topLeftCorner<3, 3>() = rigid.R;
  r.pose.topRightCorner<3, 1>() = rigid.t;
  return r;
}

}  // namespace strata
