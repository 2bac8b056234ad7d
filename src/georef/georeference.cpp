#include "georef/georeference.hpp"

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/resources.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>

namespace strata {

void GeoreferenceOptions::validate() const {
  auto fail = [](const char* name, double v, const char* rule) {
    throw InputError(fmt::format("georeference option {} must be {}, got {}", name, rule, v));
  };
  if (!(triangulation.min_angle_deg >= 0 && triangulation.min_angle_deg < 90)) {
    fail("triangulation.min_angle_deg", triangulation.min_angle_deg, "in [0, 90)");
  }
  if (!(triangulation.max_error_px > 0)) fail("triangulation.max_error_px", triangulation.max_error_px, "> 0");
  if (!(min_spread_ratio >= 0 && min_spread_ratio < 1)) fail("min_spread_ratio", min_spread_ratio, "in [0, 1)");
  if (!(outlier_threshold_m > 0)) fail("outlier_threshold_m", outlier_threshold_m, "> 0");
  if (!(outlier_sigma_factor > 0)) fail("outlier_sigma_factor", outlier_sigma_factor, "> 0");
  bundle.validate();
}

const char* to_string(MarkerRole role) {
  switch (role) {
    case MarkerRole::control:
      return "control";
    case MarkerRole::check:
      return "check";
    case MarkerRole::rejected:
      return "rejected";
  }
  return "?";
}

void transform_reconstruction(const Similarity3& s, Reconstruction& rec) {
  // X_cam = R X + t with X = R_s^T (X' - t_s) / s; scaling X_cam by s keeps the
  // projection: X_cam' = R R_s^T X' + (s t - R R_s^T t_s).
  for (auto& im : rec.images) {
    if (!im.registered) continue;
    const Eigen::Matrix3d R = im.pose.R * s.R.transpose();
    const Eigen::Vector3d t = s.scale * im.pose.t - R * s.t;
    im.pose.R = R;
    im.pose.t = t;
  }
  for (auto& p : rec.points) p.X = s.apply(p.X);
}

namespace {

struct MarkerRays {
  std::vector<Camera> cameras;
  std::vector<Eigen::Vector2d> pixels;
};

std::map<std::string, MarkerRays> collect_rays(const std::vector<MarkerObservation>& observations,
                                               const Reconstruction& rec) {
  std::map<std::string, MarkerRays> rays;
  for (const auto& o : observations) {
    if (o.image < 0 || std::size_t(o.image) >= rec.images.size()) continue;
    const auto& im = rec.images[o.image];
    if (!im.registered) continue;
    auto& r = rays[o.marker];
    r.cameras.push_back({rec.groups[im.group].intrinsics, im.pose});
    r.pixels.push_back(o.pixel);
  }
  return rays;
}

std::string names(const std::vector<std::string>& v) {
  return v.empty() ? std::string("none") : fmt::format("{}", fmt::join(v, ", "));
}

AxisRmse rmse_of(const std::vector<MarkerResidual>& rows, MarkerRole role) {
  AxisRmse r;
  for (const auto& row : rows) {
    if (row.role != role || !row.triangulated) continue;
    r.e += row.dE * row.dE;
    r.n += row.dN * row.dN;
    r.z += row.dZ * row.dZ;
    ++r.markers;
  }
  if (r.markers == 0) return r;
  const double n = double(r.markers);
  r.xyz = std::sqrt((r.e + r.n + r.z) / n);
  r.e = std::sqrt(r.e / n);
  r.n = std::sqrt(r.n / n);
  r.z = std::sqrt(r.z / n);
  return r;
}

}  // namespace

GeoreferenceSummary keep_arbitrary_frame(Reconstruction& rec) {
  rec.georeferenced = false;
  GeoreferenceSummary s;
  s.georeferenced = false;
  s.message =
      "no control markers: the layer stays in an arbitrary local frame at an arbitrary scale";
  return s;
}

GeoreferenceSummary georeference(const GeoreferenceOptions& options,
                                 const std::vector<MarkerConstraint>& markers,
                                 const std::vector<MarkerObservation>& observations,
                                 const std::vector<ImageKeypoints>& keypoints,
                                 Reconstruction& rec) {
  Stopwatch clock;
  options.validate();
  GeoreferenceSummary summary;
  {
    std::set<std::string> seen;
    for (const auto& m : markers) {
      if (!seen.insert(m.name).second) {
        throw InputError(fmt::format("georeference: marker {} is given twice", m.name));
      }
      if (m.control && !(m.sigma.minCoeff() > 0)) {
        throw InputError(fmt::format(
            "georeference: control marker {} has sigma ({}, {}, {}) m; every axis must be > 0",
            m.name, m.sigma.x(), m.sigma.y(), m.sigma.z()));
      }
    }
  }

  // The site frame keeps coordinates small (CRS minus the site origin); raw projected
  // coordinates (hundreds of kilometres) would make the adjustment badly conditioned.
  for (const auto& m : markers) {
    if (m.position.cwiseAbs().maxCoeff() > 1e4) {
      log::warn("georeference: marker {} lies {:.0f} m from the frame origin; are these raw CRS "
                "coordinates instead of site-frame ones (CRS minus the site origin)?",
                m.name, m.position.norm());
      break;
    }
  }

  // 1. Triangulate every marker in the reconstruction frame.
  const auto rays = collect_rays(observations, rec);
  std::vector<std::string> usable_names, control_names;
  std::vector<Eigen::Vector3d> usable_local, usable_site;
  std::vector<const MarkerConstraint*> usable;
  std::vector<std::string> unusable_why;
  for (const auto& m : markers) {
    if (!m.control) continue;
    control_names.push_back(m.name);
    const auto it = rays.find(m.name);
    const int views = it == rays.end() ? 0 : int(it->second.cameras.size());
    if (views < 2) {
      summary.unusable.push_back(m.name);
      unusable_why.push_back(fmt::format("{} (seen in {} registered image{})", m.name, views,
                                         views == 1 ? "" : "s"));
      continue;
    }
    const auto tri = triangulate_views(it->second.cameras, it->second.pixels, options.triangulation);
    if (!tri.ok) {
      summary.unusable.push_back(m.name);
      unusable_why.push_back(fmt::format("{} (rays {:.1f} deg apart, reprojection up to {:.1f} px)",
                                         m.name, tri.max_angle_deg, tri.max_error_px));
      continue;
    }
    usable.push_back(&m);
    usable_names.push_back(m.name);
    usable_local.push_back(tri.X);
    usable_site.push_back(m.position);
  }
  if (usable.size() < 3) {
    throw InputError(fmt::format(
        "georeference needs at least 3 control markers triangulated from >= 2 photos; "
        "{} control marker(s) given ({}), usable: {}; not usable: {}",
        control_names.size(), names(control_names), names(usable_names),
        unusable_why.empty() ? std::string("none") : fmt::format("{}", fmt::join(unusable_why, ", "))));
  }
  const double spread = planar_spread_ratio(usable_site);
  if (spread < options.min_spread_ratio) {
    throw InputError(fmt::format(
        "georeference: control markers {} are (nearly) collinear (spread ratio {:.4f} < {}): "
        "the rotation about their line is undetermined; survey a marker off that line",
        names(usable_names), spread, options.min_spread_ratio));
  }

  // 2. Robust similarity. With >= 4 markers, a consensus over every non-collinear
  // triple (exhaustive, as there are few markers; RANSAC in spirit, Fischler & Bolles
  // 1981): the triple whose similarity agrees with the most markers, within
  // max(outlier_threshold_m, outlier_sigma_factor x |sigma|), ties broken by the
  // smaller sum of squared residuals. Leave-one-out is not enough with 4 markers:
  // one blunder among the 3 others distorts every fit that includes it.
  const std::size_t n_usable = usable.size();
  auto limit_of = [&](std::size_t i) {
    return std::max(options.outlier_threshold_m, options.outlier_sigma_factor * usable[i]->sigma.norm());
  };
  auto residual_of = [&](const Similarity3& s, std::size_t i) {
    return (s.apply(usable_local[i]) - usable_site[i]).norm();
  };
  std::vector<int> inliers(n_usable);
  for (std::size_t i = 0; i < n_usable; ++i) inliers[i] = int(i);
  if (n_usable >= 4) {
    std::size_t best_count = 0;
    double best_sum2 = std::numeric_limits<double>::infinity();
    std::vector<int> best;
    for (std::size_t a = 0; a < n_usable; ++a) {
      for (std::size_t b = a + 1; b < n_usable; ++b) {
        for (std::size_t c = b + 1; c < n_usable; ++c) {
          const std::vector<Eigen::Vector3d> src{usable_local[a], usable_local[b], usable_local[c]};
          const std::vector<Eigen::Vector3d> dst{usable_site[a], usable_site[b], usable_site[c]};
          if (planar_spread_ratio(dst) < options.min_spread_ratio ||
              planar_spread_ratio(src) < options.min_spread_ratio) {
            continue;
          }
          const Similarity3 s = fit_similarity(src, dst, options.min_spread_ratio);
          std::vector<int> agree;
          double sum2 = 0;
          for (std::size_t i = 0; i < n_usable; ++i) {
            const double r = residual_of(s, i);
            if (r <= limit_of(i)) {
              agree.push_back(int(i));
              sum2 += r * r;
            }
          }
          if (agree.size() > best_count || (agree.size() == best_count && sum2 < best_sum2)) {
            best_count = agree.size();
            best_sum2 = sum2;
            best = std::move(agree);
          }
        }
      }
    }
    // Confirm on the consensus set: refit and keep those within their limit.
    std::vector<Eigen::Vector3d> src, dst;
    for (int i : best) {
      src.push_back(usable_local[i]);
      dst.push_back(usable_site[i]);
    }
    if (best.size() >= 3 && planar_spread_ratio(dst) >= options.min_spread_ratio) {
      const Similarity3 s = fit_similarity(src, dst, options.min_spread_ratio);
      std::vector<int> confirmed;
      for (std::size_t i = 0; i < n_usable; ++i) {
        if (residual_of(s, i) <= limit_of(i)) confirmed.push_back(int(i));
      }
      std::vector<Eigen::Vector3d> check;
      for (int i : confirmed) check.push_back(usable_site[i]);
      if (confirmed.size() >= 3 && planar_spread_ratio(check) >= options.min_spread_ratio) {
        inliers = confirmed;
      } else {
        inliers = best;
      }
      for (std::size_t i = 0; i < n_usable; ++i) {
        if (std::find(inliers.begin(), inliers.end(), int(i)) != inliers.end()) continue;
        summary.rejected.push_back(usable[i]->name);
        log::warn("georeference: control marker {} rejected as a gross outlier ({:.3f} m from "
                  "the similarity of the other markers, limit {:.3f} m)",
                  usable[i]->name, residual_of(s, i), limit_of(i));
      }
    }
    // No consistent triple at all: keep every marker; the residuals will show it.
    if (best.size() < 3) {
      log::warn("georeference: no 3 of the {} control markers agree with one similarity within "
                "their limit ({:.3f} m or more): the survey and the photo geometry disagree (wrong "
                "marker clicks or names, or a deformed reconstruction); all are kept, see the "
                "residual table", n_usable, options.outlier_threshold_m);
    }
  }
  std::vector<Eigen::Vector3d> src, dst;
  for (int i : inliers) {
    src.push_back(usable_local[i]);
    dst.push_back(usable_site[i]);
    summary.control_used.push_back(usable[i]->name);
  }
  summary.similarity = fit_similarity(src, dst, options.min_spread_ratio);
  for (std::size_t i = 0; i < n_usable; ++i) {
    const Eigen::Vector3d d = summary.similarity.apply(usable_local[i]) - usable_site[i];
    log::debug("georeference: {} after the similarity: dE {:+.3f} dN {:+.3f} dZ {:+.3f} m", usable[i]->name,
               d.x(), d.y(), d.z());
  }

  // 3. Into the site frame.
  transform_reconstruction(summary.similarity, rec);
  rec.georeferenced = true;

  // 4. Combined adjustment of photos and survey: only the inlier control markers.
  if (options.adjust) {
    std::set<std::string> used(summary.control_used.begin(), summary.control_used.end());
    std::vector<MarkerConstraint> constraints;
    for (const auto& m : markers) {
      if (used.count(m.name)) constraints.push_back(m);
    }
    summary.bundle = bundle_adjust(options.bundle, rec, keypoints, constraints, observations);
    log::debug("georeference: adjustment {} ({} iterations, {:.1f} s, rmse {:.3f} px)", summary.bundle.message,
               summary.bundle.iterations, summary.bundle.seconds, summary.bundle.rmse_px);
  }

  // 5. Residuals from the final cameras, photos only.
  const auto final_rays = collect_rays(observations, rec);
  const std::set<std::string> rejected(summary.rejected.begin(), summary.rejected.end());
  for (const auto& m : markers) {
    MarkerResidual row;
    row.name = m.name;
    row.role = !m.control ? MarkerRole::check
                          : (rejected.count(m.name) ? MarkerRole::rejected : MarkerRole::control);
    const auto it = final_rays.find(m.name);
    if (it != final_rays.end()) {
      row.images = int(it->second.cameras.size());
      const auto tri =
          triangulate_views(it->second.cameras, it->second.pixels, options.triangulation);
      // The reprojection gate is not applied here: a large error is what this row reports.
      if (row.images >= 2 && tri.X.allFinite() &&
          tri.max_angle_deg >= options.triangulation.min_angle_deg &&
          std::isfinite(tri.rmse_px)) {
        row.triangulated = true;
        const Eigen::Vector3d d = tri.X - m.position;
        row.dE = d.x();
        row.dN = d.y();
        row.dZ = d.z();
        row.reprojection_px = tri.rmse_px;
      }
    }
    if (!m.control && !row.triangulated) summary.unusable.push_back(m.name);
    summary.residuals.push_back(row);
  }
  summary.control = rmse_of(summary.residuals, MarkerRole::control);
  summary.check = rmse_of(summary.residuals, MarkerRole::check);
  summary.georeferenced = true;
  summary.seconds = clock.seconds();
  summary.message = fmt::format(
      "georeferenced on {} control markers ({} rejected); control RMSE {:.4f} m, check RMSE "
      "{:.4f} m over {} check marker(s)",
      summary.control_used.size(), summary.rejected.size(), summary.control.xyz,
      summary.check.xyz, summary.check.markers);
  return summary;
}

}  // namespace strata
