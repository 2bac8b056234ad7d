#include "georef/georeference.hpp"

#include "core/statistics.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "core/resources.hpp"
#include "sfm/quality.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <iterator>
#include <map>
#include <numeric>
#include <optional>
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
  if (!(duplicate_px >= 0)) fail("duplicate_px", duplicate_px, ">= 0");
  if (!(horizontal_only_sigma_m > 0)) fail("horizontal_only_sigma_m", horizontal_only_sigma_m, "> 0");
  if (!(unknown_height_sigma_m >= horizontal_only_sigma_m))
    fail("unknown_height_sigma_m", unknown_height_sigma_m, ">= horizontal_only_sigma_m");
  if (!(min_observation_sigma_px > 0)) fail("min_observation_sigma_px", min_observation_sigma_px, "> 0");
  if (max_rejection_rounds < 0) fail("max_rejection_rounds", max_rejection_rounds, ">= 0");
  if (!(max_relative_misfit > 0)) fail("max_relative_misfit", max_relative_misfit, "> 0");
  if (!(max_bending_factor >= 1)) fail("max_bending_factor", max_bending_factor, ">= 1");
  if (!(min_bent_rmse_px > 0)) fail("min_bent_rmse_px", min_bent_rmse_px, "> 0");
  bundle.validate();
  rays.validate();
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

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
// metres: the smallest dome or bowl of the height residuals named as a bent block.
constexpr double kMinBendingM = 0.01;

// One observation of a marker in a registered image.
struct Ray {
  int image = -1;  // index into rec.images
  Eigen::Vector2d pixel;
  bool kept = true;        // agrees with the marker's other rays (and is not excluded)
  std::string excluded;    // non-empty: left out for this reason (a duplicate click)
  double error_px = 0;     // to the marker's fitted point
  double sigma_px = 0;     // what this photo is expected to achieve on the marker
};
using RaysByMarker = std::map<std::string, std::vector<Ray>>;
using FitsByMarker = std::map<std::string, MarkerRayFit>;

RaysByMarker collect_rays(const std::vector<MarkerObservation>& observations, const Reconstruction& rec) {
  RaysByMarker rays;
  for (const auto& o : observations) {
    if (o.image < 0 || std::size_t(o.image) >= rec.images.size()) continue;
    if (!rec.images[o.image].registered) continue;
    Ray r;
    r.image = o.image;
    r.pixel = o.pixel;
    rays[o.marker].push_back(r);
  }
  return rays;
}

Camera camera_of(const Reconstruction& rec, int image) {
  const auto& im = rec.images[image];
  return {rec.groups[im.group].intrinsics, im.pose};
}

std::size_t kept_count(const std::vector<Ray>& rays) {
  return std::size_t(std::count_if(rays.begin(), rays.end(), [](const Ray& r) { return r.kept; }));
}

// Fits one marker from its rays that are not excluded (marker_rays.hpp) with the
// current cameras, and marks which agree.
MarkerRayFit fit_rays(const Reconstruction& rec, std::vector<Ray>& rays, const MarkerRayOptions& o) {
  std::vector<Camera> cams;
  std::vector<Eigen::Vector2d> px;
  std::vector<std::size_t> index;
  for (std::size_t j = 0; j < rays.size(); ++j) {
    rays[j].kept = false;
    rays[j].error_px = kNaN;
    rays[j].sigma_px = 0;
    if (!rays[j].excluded.empty()) continue;
    cams.push_back(camera_of(rec, rays[j].image));
    px.push_back(rays[j].pixel);
    index.push_back(j);
  }
  MarkerRayFit fit = fit_marker_rays(cams, px, o);
  for (std::size_t k = 0; k < index.size(); ++k) {
    auto& r = rays[index[k]];
    r.kept = fit.rays[k].agrees && fit.agreeing >= 2;
    r.error_px = fit.rays[k].error_px;
    r.sigma_px = fit.rays[k].sigma_px;
  }
  return fit;
}

double pixel_distance(const Reconstruction& rec, int image, const Eigen::Vector3d& X,
                      const Eigen::Vector2d& pixel) {
  if (!X.allFinite()) return kNaN;
  const auto p = camera_of(rec, image).project(X);
  return p ? (*p - pixel).norm() : kInf;
}

std::string names(const std::vector<std::string>& v) {
  return v.empty() ? std::string("none") : fmt::format("{}", fmt::join(v, ", "));
}

bool plan_only(const MarkerConstraint& m, const GeoreferenceOptions& o) {
  return m.sigma.z() >= o.horizontal_only_sigma_m;
}

// Survey sigma that bounds a residual: plan for horizontal control, 3D otherwise.
double survey_sigma(const MarkerConstraint& m, bool plan) {
  return plan ? std::hypot(m.sigma.x(), m.sigma.y()) : m.sigma.norm();
}

double residual_norm(const Eigen::Vector3d& d, bool plan) {
  return plan ? std::hypot(d.x(), d.y()) : d.norm();
}

AxisRmse rmse_of(const std::vector<MarkerResidual>& rows, MarkerRole role, bool leave_one_out) {
  AxisRmse r;
  for (const auto& row : rows) {
    if (row.role != role || !row.triangulated || (leave_one_out && !row.loo)) continue;
    const double de = leave_one_out ? row.loo_dE : row.dE;
    const double dn = leave_one_out ? row.loo_dN : row.dN;
    const double dz = leave_one_out ? row.loo_dZ : row.dZ;
    r.e += de * de;
    r.n += dn * dn;
    ++r.markers;
    if (row.height_known) {
      r.z += dz * dz;
      ++r.markers_z;
    }
  }
  if (r.markers == 0) return r;
  r.e = std::sqrt(r.e / double(r.markers));
  r.n = std::sqrt(r.n / double(r.markers));
  r.z = r.markers_z ? std::sqrt(r.z / double(r.markers_z)) : 0.0;
  r.horizontal = std::hypot(r.e, r.n);
  r.xyz = std::sqrt(r.e * r.e + r.n * r.n + r.z * r.z);
  return r;
}

// The marker's rays in words, when they do not meet as one point. `metric`: the frame
// is the site frame (metres); before the georeference the scale is arbitrary and the
// scatter is given in pixels only.
std::string diagnose_marker(const MarkerRayFit& fit, const std::vector<Ray>& rays, const Reconstruction& rec,
                            double click_sigma_px, bool metric) {
  const std::size_t fitted = std::size_t(std::count_if(rays.begin(), rays.end(), [](const Ray& r) {
    return r.excluded.empty();
  }));
  if (fitted < 2) return "";
  if (fit.too_dispersed) {
    return fmt::format("its {} rays scatter by {:.0f} % of the viewing distance: not one point (clicks on "
                       "different objects, or a wrong name)", fitted, 100 * fit.dispersion / fit.mean_depth);
  }
  if (fit.agreeing < 2) return fmt::format("no two of its {} rays meet: check its name and clicks", fitted);
  std::string text;
  const double dispersion_px = fit.mean_footprint > 0 ? fit.dispersion / fit.mean_footprint : 0;
  if (dispersion_px > 2 * click_sigma_px) {
    const std::string size =
        metric ? fmt::format(" ({:.1f} mm at {:.2f} m)", 1000 * fit.dispersion, fit.mean_depth) : std::string();
    text = fmt::format("its clicks scatter by {:.1f} px{} about one point: an object seen from different sides, "
                       "or positions placed by another program; weighted by that dispersion",
                       dispersion_px, size);
  }
  const std::size_t disagree = fitted - std::size_t(fit.agreeing);
  if (disagree == 1) {
    for (const auto& r : rays) {
      if (r.excluded.empty() && !r.kept) {
        text += fmt::format("{}one click disagrees ({}, {:.1f} px off)", text.empty() ? "" : "; ",
                            rec.images[r.image].name, r.error_px);
      }
    }
  } else if (disagree > 1) {
    text += fmt::format("{}{} of its {} clicks disagree with the others (listed as dropped)",
                        text.empty() ? "" : "; ", disagree, fitted);
  }
  return text;
}

// Residuals that grow toward the photo edges over all markers point at the lens model
// rather than at the markers: compare the normalised misfit (error / expected) of the
// agreeing rays in the outer part of the photos with the inner part.
std::optional<std::string> diagnose_lens(const RaysByMarker& rays, const Reconstruction& rec) {
  double inner = 0, outer = 0;
  int n_inner = 0, n_outer = 0;
  std::set<std::string> outer_markers;
  for (const auto& [name, list] : rays) {
    for (const auto& r : list) {
      if (!r.kept || !(r.sigma_px > 0)) continue;
      const auto& k = rec.groups[rec.images[r.image].group].intrinsics;
      const double half_diagonal = 0.5 * std::hypot(k.width, k.height);
      const double radius = std::hypot(r.pixel.x() - k.cx, r.pixel.y() - k.cy) / half_diagonal;
      const double z2 = (r.error_px * r.error_px) / (r.sigma_px * r.sigma_px);
      if (radius < 0.5) {
        inner += z2;
        ++n_inner;
      } else if (radius > 0.75) {
        outer += z2;
        ++n_outer;
        outer_markers.insert(name);
      }
    }
  }
  // Enough rays on both sides, from more than one marker, and a clear contrast (the
  // normalised misfit is 1 on average when the model holds).
  if (n_inner < 5 || n_outer < 5 || outer_markers.size() < 2) return std::nullopt;
  const double ratio = (outer / n_outer) / std::max(inner / n_inner, 1e-12);
  if (ratio < 4 || outer / n_outer < 2) return std::nullopt;
  return fmt::format("marker rays near the photo edges miss {:.1f} x more than near the centre ({} and {} rays): "
                     "the lens model may be too simple for this camera (try process --camera-model brown, or a "
                     "known calibration: strata camera set)",
                     std::sqrt(ratio), n_outer, n_inner);
}

// A photo whose marker clicks all disagree with the other photos of those markers is
// placed wrong by the alignment, not clicked wrong: several independent clicks do not
// fail together in one photo. Named when at least 3 markers judged by their other rays
// (2 or more agreeing) are seen in it and at least 3 in 4 of them disagree.
std::vector<std::string> diagnose_misplaced_photos(const RaysByMarker& rays,
                                                   const FitsByMarker& fits,
                                                   const Reconstruction& rec) {
  struct Count {
    int judged = 0, disagree = 0;
    double least = std::numeric_limits<double>::infinity(), most = 0;
  };
  std::map<int, Count> by_image;
  for (const auto& [name, list] : rays) {
    const auto fit = fits.find(name);
    if (fit == fits.end() || fit->second.agreeing < 2) continue;
    for (const auto& r : list) {
      if (!r.excluded.empty()) continue;
      Count& c = by_image[r.image];
      ++c.judged;
      if (!r.kept) {
        ++c.disagree;
        c.least = std::min(c.least, r.error_px);
        c.most = std::max(c.most, r.error_px);
      }
    }
  }
  std::vector<std::string> out;
  for (const auto& [image, c] : by_image) {
    if (c.judged < 3 || 4 * c.disagree < 3 * c.judged) continue;
    out.push_back(fmt::format(
        "photo {} is probably placed wrong by the alignment, not clicked wrong: {} of the {} markers it "
        "sees disagree with their other photos ({:.0f}-{:.0f} px); its clicks were left out. Check the photo "
        "(blurred, another scene, little overlap with its neighbours) and its position in the report",
        rec.images[image].name, c.disagree, c.judged, c.least, c.most));
  }
  return out;
}

// A block bent by an unmodelled lens or weak geometry shows as a dome or bowl: the
// markers' height residuals grow with the square of their plan distance from the
// block's centre. Fitted as dZ = a + b r^2 over the markers with a known height; named
// when it explains at least half their scatter and reaches `limit_m` at the farthest
// marker (the control markers are pulled onto the survey by the adjustment, so the
// pattern shows mostly on the others: a strict fit would never fire).
std::optional<std::string> diagnose_bending(const std::vector<MarkerResidual>& rows,
                                            const std::map<std::string, const MarkerConstraint*>& by_name,
                                            double limit_m) {
  std::vector<Eigen::Vector2d> plan;
  std::vector<double> dz;
  for (const auto& r : rows) {
    if (!r.triangulated || !r.height_known) continue;
    plan.push_back(by_name.at(r.name)->position.head<2>());
    dz.push_back(r.dZ);
  }
  if (plan.size() < 5) return std::nullopt;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (const auto& p : plan) centre += p;
  centre /= double(plan.size());
  Eigen::MatrixXd A(plan.size(), 2);
  Eigen::VectorXd b(plan.size());
  double r2_max = 0;
  for (std::size_t i = 0; i < plan.size(); ++i) {
    const double r2 = (plan[i] - centre).squaredNorm();
    A(Eigen::Index(i), 0) = 1;
    A(Eigen::Index(i), 1) = r2;
    b(Eigen::Index(i)) = dz[i];
    r2_max = std::max(r2_max, r2);
  }
  const Eigen::Vector2d x = A.colPivHouseholderQr().solve(b);
  const double mean = b.mean();
  const double total = (b.array() - mean).square().sum();
  const double left = (A * x - b).squaredNorm();
  const double edge = std::abs(x(1)) * r2_max;  // metres, at the farthest marker
  if (!(total > 0) || left > 0.5 * total || edge < limit_m) return std::nullopt;
  return fmt::format("the markers' height residuals follow a {} ({:.0f} mm at {:.1f} m from the centre, {:.0f} % of "
                     "their scatter): the reconstruction is bent, typically by lens distortion the model misses or "
                     "photos taken too nearly parallel; add oblique photos from around the site, or use a known "
                     "calibration (strata camera set)",
                     x(1) > 0 ? "bowl" : "dome", 1000 * edge, std::sqrt(r2_max), 100 * (1 - left / total));
}

// Refuses a georeference that these photos cannot carry (another place, clicks made on
// other photos, the survey of another site): throws InputError when
//  - the adjustment reached the survey only by bending the photos: the keypoint
//    reprojection RMSE rose from `rmse_before_px` (the free block) beyond
//    max_bending_factor times that and min_bent_rmse_px; or
//  - the control markers kept miss their survey by more than max_relative_misfit of
//    their spread (RMS about their centre) and by more than outlier_sigma_factor times
//    their survey sigma, while most of them agree only through the scatter of their
//    clicks (dispersion beyond twice the click sigma: their limits are wide because the
//    clicks are not one point). Sharp markers that misfit (a poor survey, a bent block:
//    copr fits its survey to 5 %) are kept with the warnings of the residual table.
// `scattered`: the control markers clicked in two or more photos whose rays were not one
// point; `clicked`: every control marker.
void refuse_foreign_photos(const std::vector<MarkerResidual>& rows,
                           const std::map<std::string, const MarkerConstraint*>& by_name,
                           const std::vector<std::string>& clicked, const std::vector<std::string>& scattered,
                           double click_sigma_px, double rmse_before_px, double rmse_after_px,
                           const GeoreferenceOptions& options) {
  const std::string causes =
      "the photos show another place, the clicks were made on other photos (the same file names?), or the "
      "survey is of another site or CRS; nothing was recorded (see 'strata markers DIR')";
  if (rmse_after_px > std::max(options.min_bent_rmse_px, options.max_bending_factor * rmse_before_px)) {
    throw InputError(fmt::format(
        "georeference: these photos do not fit the survey: the adjustment met the survey only by bending the "
        "photos (keypoint reprojection RMSE {:.2f} px, {:.2f} px before): {}",
        rmse_after_px, rmse_before_px, causes));
  }
  std::vector<const MarkerResidual*> control;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& row : rows) {
    if (row.role != MarkerRole::control || !row.triangulated) continue;
    control.push_back(&row);
    centroid += by_name.at(row.name)->position;
  }
  if (control.size() < 3) return;
  centroid /= double(control.size());
  double misfit2 = 0, spread2 = 0, sigma2 = 0;
  std::size_t dispersed = 0;
  for (const MarkerResidual* row : control) {
    const MarkerConstraint& m = *by_name.at(row->name);
    const bool plan = !row->height_known;
    misfit2 += std::pow(residual_norm({row->dE, row->dN, row->dZ}, plan), 2);
    spread2 += std::pow(residual_norm(m.position - centroid, plan), 2);
    sigma2 += std::pow(survey_sigma(m, plan), 2);
    if (row->dispersion_px > 2 * click_sigma_px) ++dispersed;
  }
  const double n = double(control.size());
  const double misfit = std::sqrt(misfit2 / n), spread = std::sqrt(spread2 / n), sigma = std::sqrt(sigma2 / n);
  if (!(misfit > options.max_relative_misfit * spread && misfit > options.outlier_sigma_factor * sigma &&
        2 * dispersed > control.size())) {
    return;
  }
  std::vector<std::string> kept;
  for (const MarkerResidual* row : control) kept.push_back(row->name);
  throw InputError(fmt::format(
      "georeference: these photos do not fit the survey: control markers {} miss their surveyed positions by "
      "{:.3f} m RMS, {:.0f} % of their spread ({:.2f} m RMS about their centre), far beyond their survey sigma "
      "({:.3f} m), and the clicks of {} of them scatter instead of meeting at one point{}: {}",
      names(kept), misfit, 100 * misfit / spread, spread, sigma, dispersed,
      scattered.empty() ? std::string()
                        : fmt::format("; those of {} of the {} control markers are not one point at all ({})",
                                      scattered.size(), clicked.size(), names(scattered)),
      causes));
}

// The up direction of the reconstruction's ground: the normal of the sparse points'
// least-squares plane (smallest principal axis), turned towards the cameras (which
// look down at the ground from above it).
Eigen::Vector3d ground_up(const Reconstruction& rec) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : rec.points) mean += p.X;
  mean /= double(std::max<std::size_t>(1, rec.points.size()));
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : rec.points) cov += (p.X - mean) * (p.X - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  Eigen::Vector3d up = eig.eigenvectors().col(0);
  Eigen::Vector3d cameras = Eigen::Vector3d::Zero();
  int n = 0;
  for (const auto& im : rec.images) {
    if (!im.registered) continue;
    cameras += im.pose.centre();
    ++n;
  }
  if (n > 0 && up.dot(cameras / n - mean) < 0) up = -up;
  return up.normalized();
}

// Plan-only control (every height unknown) fixes scale, the rotation about the
// vertical and the plan position, but not the tilt: a 3D fit then tilts the block to
// soak up plan misfits (a real set tilted 40 degrees that way). The tilt is taken from
// the ground instead: level the block so that its ground plane is horizontal, then fit
// a 4-parameter plan similarity (Umeyama 1991 in 2D) of the markers' photo positions
// onto their surveyed E, N; the height offset puts the markers' mean at their nominal
// height. `local` in the current frame, `survey` in the site frame.
Similarity3 level_plan_similarity(const Reconstruction& rec, const std::vector<Eigen::Vector3d>& local,
                                  const std::vector<Eigen::Vector3d>& survey) {
  const Eigen::Matrix3d L = Eigen::Quaterniond::FromTwoVectors(ground_up(rec), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  Eigen::Matrix2Xd src(2, local.size()), dst(2, local.size());
  for (std::size_t i = 0; i < local.size(); ++i) {
    src.col(Eigen::Index(i)) = (L * local[i]).head<2>();
    dst.col(Eigen::Index(i)) = survey[i].head<2>();
  }
  const Eigen::Matrix3d T = Eigen::umeyama(src, dst, true);  // 2D similarity, homogeneous
  const double scale = std::sqrt(std::abs(T.block<2, 2>(0, 0).determinant()));
  Eigen::Matrix3d Rz = Eigen::Matrix3d::Identity();
  Rz.block<2, 2>(0, 0) = T.block<2, 2>(0, 0) / scale;
  Similarity3 s;
  s.scale = scale;
  s.R = Rz * L;
  s.t = Eigen::Vector3d(T(0, 2), T(1, 2), 0);
  double dz = 0;
  for (std::size_t i = 0; i < local.size(); ++i) dz += survey[i].z() - s.apply(local[i]).z();
  s.t.z() = dz / double(local.size());
  return s;
}

using MarkersByName = std::map<std::string, const MarkerConstraint*>;

// Refuses a marker given twice and control without a positive sigma on every axis.
MarkersByName index_markers(const std::vector<MarkerConstraint>& markers) {
  MarkersByName by_name;
  for (const auto& m : markers) {
    if (!by_name.emplace(m.name, &m).second) {
      throw InputError(fmt::format("georeference: marker {} is given twice", m.name));
    }
    if (m.control && !(m.sigma.minCoeff() > 0)) {
      throw InputError(fmt::format(
          "georeference: control marker {} has sigma ({}, {}, {}) m; every axis must be > 0",
          m.name, m.sigma.x(), m.sigma.y(), m.sigma.z()));
    }
  }
  return by_name;
}

// The site frame keeps coordinates small (CRS minus the site origin); raw projected
// coordinates (hundreds of kilometres) would make the adjustment badly conditioned.
void warn_of_raw_crs_coordinates(const std::vector<MarkerConstraint>& markers) {
  for (const auto& m : markers) {
    if (m.position.cwiseAbs().maxCoeff() > 1e4) {
      log::warn("georeference: marker {} lies {:.0f} m from the frame origin; are these raw CRS "
                "coordinates instead of site-frame ones (CRS minus the site origin)?",
                m.name, m.position.norm());
      break;
    }
  }
}

// The markers' rays in the registered images and their fits with the current cameras,
// refitted whenever the cameras move.
struct MarkerRays {
  RaysByMarker rays;
  FitsByMarker fits;
  MarkerRayOptions options;         // click_sigma_px: the marker sigma of the adjustment
  std::vector<Blunder> duplicates;  // clicks left out as another marker's target
};

// The observations of known markers in registered images, not fitted yet.
MarkerRays collect_marker_rays(const GeoreferenceOptions& options, const std::vector<MarkerObservation>& observations,
                               const MarkersByName& by_name, const Reconstruction& rec) {
  MarkerRays m;
  m.rays = collect_rays(observations, rec);
  for (auto it = m.rays.begin(); it != m.rays.end();) {  // observations of unknown markers
    it = by_name.count(it->first) ? std::next(it) : m.rays.erase(it);
  }
  m.options = options.rays;
  m.options.min_angle_deg = options.triangulation.min_angle_deg;
  m.options.click_sigma_px = options.bundle.marker_sigma_px;
  return m;
}

void fit_markers(const Reconstruction& rec, MarkerRays& m) {
  for (auto& [name, list] : m.rays) m.fits[name] = fit_rays(rec, list, m.options);
}

struct DuplicateClick {
  std::string marker;
  std::size_t ray;
  std::string reason;
};

// Two markers seen at one pixel of one photo: the one whose other photos agree keeps
// it. `final`: the cameras are adjusted, so an unconfirmed pair is dropped as a whole
// too (before the adjustment, the SfM cameras may not confirm anything yet).
std::vector<DuplicateClick> duplicate_clicks(const MarkerRays& m, double duplicate_px, bool final) {
  auto confirmed = [&](const std::string& name, std::size_t j) {
    return m.rays.at(name)[j].kept && m.fits.at(name).ok && m.fits.at(name).agreeing >= 3;
  };
  std::map<int, std::vector<std::pair<std::string, std::size_t>>> by_image;
  for (const auto& [name, list] : m.rays) {
    for (std::size_t j = 0; j < list.size(); ++j) {
      if (list[j].excluded.empty()) by_image[list[j].image].emplace_back(name, j);
    }
  }
  std::vector<DuplicateClick> to_drop;
  for (const auto& [image, seen] : by_image) {
    for (std::size_t a = 0; a < seen.size(); ++a) {
      for (std::size_t b = a + 1; b < seen.size(); ++b) {
        const auto& [na, ja] = seen[a];
        const auto& [nb, jb] = seen[b];
        if (na == nb) continue;
        const double d = (m.rays.at(na)[ja].pixel - m.rays.at(nb)[jb].pixel).norm();
        if (d > duplicate_px) continue;
        const bool ca = confirmed(na, ja), cb = confirmed(nb, jb);
        if (ca && cb) continue;  // both agree with their other photos: keep both
        if (!ca && !cb && !final) continue;
        auto why = [&](const std::string& other, bool other_confirmed) {
          return other_confirmed
                     ? fmt::format("at the same pixel as {} ({:.1f} px apart), whose other photos "
                                   "confirm that target is {}",
                                   other, d, other)
                     : fmt::format("at the same pixel as {} ({:.1f} px apart); neither is confirmed "
                                   "by two other photos",
                                   other, d);
        };
        if (!ca) to_drop.push_back({na, ja, why(nb, cb)});
        if (!cb) to_drop.push_back({nb, jb, why(na, ca)});
      }
    }
  }
  return to_drop;
}

// Fits every marker, then leaves out the duplicate clicks and refits their markers.
void screen_markers(const Reconstruction& rec, double duplicate_px, bool final, MarkerRays& m) {
  fit_markers(rec, m);
  std::set<std::string> refit;
  for (const auto& [name, j, reason] : duplicate_clicks(m, duplicate_px, final)) {
    auto& ray = m.rays.at(name)[j];
    if (!ray.excluded.empty()) continue;
    ray.excluded = reason;
    m.duplicates.push_back({name, rec.images[ray.image].name, 0.0, "px", reason});
    refit.insert(name);
  }
  for (const auto& name : refit) m.fits[name] = fit_rays(rec, m.rays.at(name), m.options);
}

std::vector<MarkerObservation> kept_observations(const RaysByMarker& rays) {
  std::vector<MarkerObservation> kept;
  for (const auto& [name, list] : rays) {
    for (const auto& r : list) {
      if (r.kept) kept.push_back({name, r.image, r.pixel, r.sigma_px});
    }
  }
  return kept;
}

// A usable control marker, in the reconstruction frame.
struct Control {
  const MarkerConstraint* m;
  Eigen::Vector3d local;
  double footprint;   // ground size of a pixel at the marker, reconstruction units
  double dispersion;  // the marker's scatter about its point, reconstruction units
  bool plan;
};

struct ControlSet {
  std::vector<Control> usable;
  std::vector<std::string> names;         // every control marker given
  std::vector<std::string> usable_names;
  std::vector<std::string> unusable;      // control markers the photos cannot place
  std::vector<std::string> unusable_why;  // the same, each with its reason
  std::vector<Blunder> blunders;          // markers not used, their rays not one point
};

// The control markers that are seen in 2 photos or more and whose rays meet.
ControlSet select_control(const GeoreferenceOptions& options, const std::vector<MarkerConstraint>& markers,
                          const MarkerRays& m, const Reconstruction& rec) {
  ControlSet set;
  for (const auto& marker : markers) {
    if (!marker.control) continue;
    set.names.push_back(marker.name);
    const auto it = m.rays.find(marker.name);
    const std::size_t views = it == m.rays.end() ? 0 : it->second.size();
    if (views < 2) {
      set.unusable.push_back(marker.name);
      set.unusable_why.push_back(fmt::format("{} (seen in {} registered image{})", marker.name, views,
                                             views == 1 ? "" : "s"));
      continue;
    }
    const MarkerRayFit& fit = m.fits.at(marker.name);
    if (!fit.ok) {
      const std::string why = diagnose_marker(fit, it->second, rec, m.options.click_sigma_px, false);
      set.unusable.push_back(marker.name);
      set.unusable_why.push_back(fmt::format("{} ({} of {} rays agree, {:.1f} deg apart{}{})", marker.name,
                                             fit.agreeing, views, fit.max_angle_deg, why.empty() ? "" : ": ", why));
      set.blunders.push_back({marker.name, "", kNaN, "px",
                              fmt::format("marker not used: {}", why.empty() ? "its rays are too close to "
                                                                               "parallel"
                                                                             : why)});
      continue;
    }
    set.usable.push_back({&marker, fit.X, fit.mean_footprint, fit.dispersion, plan_only(marker, options)});
    set.usable_names.push_back(marker.name);
  }
  return set;
}

// Throws InputError unless at least 3 usable control markers span a plane.
void require_control_geometry(const GeoreferenceOptions& options, const ControlSet& set) {
  if (set.usable.size() < 3) {
    throw InputError(fmt::format(
        "georeference needs at least 3 control markers triangulated from >= 2 photos; "
        "{} control marker(s) seen in the photos ({}), usable: {}; not usable: {}",
        set.names.size(), names(set.names), names(set.usable_names),
        set.unusable_why.empty() ? std::string("none") : fmt::format("{}", fmt::join(set.unusable_why, ", "))));
  }
  std::vector<Eigen::Vector3d> usable_site;
  for (const auto& c : set.usable) usable_site.push_back(c.m->position);
  const double spread = planar_spread_ratio(usable_site);
  if (spread < options.min_spread_ratio) {
    throw InputError(fmt::format(
        "georeference: control markers {} are (nearly) collinear (spread ratio {:.4f} < {}): "
        "the rotation about their line is undetermined; survey a marker off that line",
        names(set.usable_names), spread, options.min_spread_ratio));
  }
  const auto n_plan = std::count_if(set.usable.begin(), set.usable.end(), [](const Control& c) { return c.plan; });
  if (n_plan > 0) {
    log::info("georeference: {} of {} control markers are horizontal control (height sigma >= {} m): "
              "their heights weigh only as a weak prior{}",
              n_plan, set.usable.size(), options.horizontal_only_sigma_m,
              std::size_t(n_plan) == set.usable.size() ? "; the level of the block rests on it" : "");
  }
}

// The limit of a marker: its survey sigma and its photo precision (the click sigma in
// pixels on the ground, and the marker's own dispersion), times outlier_sigma_factor,
// at least outlier_threshold_m.
double limit_of(const Control& c, double scale, double click_sigma_px, const GeoreferenceOptions& options) {
  const double photo = std::hypot(click_sigma_px * c.footprint, c.dispersion) * scale;
  return std::max(options.outlier_threshold_m,
                  options.outlier_sigma_factor * std::hypot(survey_sigma(*c.m, c.plan), photo));
}

double residual_of(const std::vector<Control>& usable, const Similarity3& s, std::size_t i) {
  return residual_norm(s.apply(usable[i].local) - usable[i].m->position, usable[i].plan);
}

Similarity3 fit_control(const std::vector<Control>& usable, const std::vector<int>& idx, double min_spread_ratio) {
  std::vector<Eigen::Vector3d> src, dst, sigma;
  for (int i : idx) {
    src.push_back(usable[i].local);
    dst.push_back(usable[i].m->position);
    sigma.push_back(usable[i].m->sigma);
  }
  return fit_similarity_weighted(src, dst, sigma, min_spread_ratio);
}

double spread_of(const std::vector<Control>& usable, const std::vector<int>& idx) {
  std::vector<Eigen::Vector3d> src, dst;
  for (int i : idx) {
    src.push_back(usable[i].local);
    dst.push_back(usable[i].m->position);
  }
  return std::min(planar_spread_ratio(src), planar_spread_ratio(dst));
}

// An agreement of k of the n usable markers rejects at most a third of them; beyond
// that, the survey and the photos disagree broadly (see reject_gross_outliers).
bool is_agreement(std::size_t k, std::size_t n) { return 3 * (n - k) <= n; }

// Consensus over every non-collinear triple (exhaustive: there are few markers;
// RANSAC in spirit, Fischler & Bolles 1981): the markers that agree with the triple
// whose similarity agrees with the most, ties broken by the smaller sum of squared
// residuals. Leave-one-out alone fails with 4 markers: one blunder distorts every fit
// with it.
std::vector<int> consensus(const std::vector<Control>& usable, double click_sigma_px,
                           const GeoreferenceOptions& options) {
  const std::size_t n_usable = usable.size();
  std::size_t best_count = 0;
  double best_sum2 = kInf;
  std::vector<int> best;
  for (std::size_t a = 0; a < n_usable; ++a) {
    for (std::size_t b = a + 1; b < n_usable; ++b) {
      for (std::size_t c = b + 1; c < n_usable; ++c) {
        const std::vector<int> triple{int(a), int(b), int(c)};
        if (spread_of(usable, triple) < options.min_spread_ratio) continue;
        const Similarity3 s = fit_control(usable, triple, options.min_spread_ratio);
        std::vector<int> agree;
        double sum2 = 0;
        for (std::size_t i = 0; i < n_usable; ++i) {
          const double r = residual_of(usable, s, i);
          if (r <= limit_of(usable[i], s.scale, click_sigma_px, options)) {
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
  return best;
}

struct ControlInliers {
  std::vector<int> inliers;            // into the usable markers
  std::vector<std::string> rejected;   // gross outliers against the survey
  std::vector<Blunder> blunders;       // the same, with their residuals
};

// The control markers that drive the similarity: from 4 usable markers on, those of a
// consensus confirmed on its own refit; every usable marker otherwise.
ControlInliers reject_gross_outliers(const std::vector<Control>& usable, double click_sigma_px,
                                     const GeoreferenceOptions& options) {
  const std::size_t n_usable = usable.size();
  ControlInliers out;
  out.inliers.resize(n_usable);
  std::iota(out.inliers.begin(), out.inliers.end(), 0);
  if (n_usable < 4) return out;
  const std::vector<int> best = consensus(usable, click_sigma_px, options);
  // A consensus must be a majority: when more than a third of the markers would be
  // rejected, the survey and the photos disagree broadly (a survey of metre-level
  // accuracy, a deformed block) and rejecting most of the markers would hide it
  // behind a perfect fit on the few left.
  const bool broad = !is_agreement(best.size(), n_usable);
  if (broad) {
    log::warn("georeference: only {} of the {} control markers agree with one similarity within "
              "their limit: survey and photo geometry disagree broadly (not a few blunders); all are "
              "kept, see the leave-one-out and distance misfits in the residual table",
              best.size(), n_usable);
  } else if (best.size() >= 3 && spread_of(usable, best) >= options.min_spread_ratio) {
    // Confirm on the consensus set: refit and keep those within their limit.
    const Similarity3 s = fit_control(usable, best, options.min_spread_ratio);
    std::vector<int> confirmed;
    for (std::size_t i = 0; i < n_usable; ++i) {
      if (residual_of(usable, s, i) <= limit_of(usable[i], s.scale, click_sigma_px, options))
        confirmed.push_back(int(i));
    }
    // The confirmed set must still be an agreement: a consensus of four of six that
    // shrinks to three on its own refit was four markers whose limits (wide, from
    // dispersed clicks) happened to overlap.
    if (is_agreement(confirmed.size(), n_usable) && spread_of(usable, confirmed) >= options.min_spread_ratio) {
      out.inliers = confirmed;
    } else {
      log::warn("georeference: {} control markers agree with one similarity, but only {} of the {} "
                "refitted on them: survey and photo geometry disagree broadly (not a few blunders); "
                "all are kept", best.size(), confirmed.size(), n_usable);
    }
    for (std::size_t i = 0; i < n_usable; ++i) {
      if (std::find(out.inliers.begin(), out.inliers.end(), int(i)) != out.inliers.end()) continue;
      const double r = residual_of(usable, s, i), limit = limit_of(usable[i], s.scale, click_sigma_px, options);
      out.rejected.push_back(usable[i].m->name);
      out.blunders.push_back({usable[i].m->name, "", r, "m",
                              fmt::format("{:.3f} m {}from the similarity of the {} agreeing control "
                                          "markers (limit {:.3f} m): survey and photos disagree",
                                          r, usable[i].plan ? "in plan " : "", out.inliers.size(), limit)});
    }
  } else if (best.size() < 3) {
    // No consistent triple at all: keep every marker; the residuals will show it.
    log::warn("georeference: no 3 of the {} control markers agree with one similarity within "
              "their limit ({:.3f} m or more): the survey and the photo geometry disagree (wrong "
              "marker clicks or names, or a deformed reconstruction); all are kept, see the "
              "residual table", n_usable, options.outlier_threshold_m);
  }
  return out;
}

// The similarity of the inliers; levelled on the ground when all are plan only.
Similarity3 control_similarity(const Reconstruction& rec, const std::vector<Control>& usable,
                               const std::vector<int>& inliers, bool plan_only_control,
                               const GeoreferenceOptions& options) {
  Similarity3 similarity = fit_control(usable, inliers, options.min_spread_ratio);
  if (plan_only_control) {
    std::vector<Eigen::Vector3d> src, dst;
    for (int i : inliers) {
      src.push_back(usable[i].local);
      dst.push_back(usable[i].m->position);
    }
    similarity = level_plan_similarity(rec, src, dst);
    log::info("georeference: every control marker is plan only: the block is levelled on its ground (the "
              "sparse points' plane) and fitted in plan");
  }
  for (const auto& c : usable) {
    const Eigen::Vector3d d = similarity.apply(c.local) - c.m->position;
    log::debug("georeference: {} after the similarity: dE {:+.3f} dN {:+.3f} dZ {:+.3f} m",
               c.m->name, d.x(), d.y(), d.z());
  }
  return similarity;
}

// What the combined adjustment of photos and survey reads, run after run.
struct Adjustment {
  const GeoreferenceOptions& options;
  const std::vector<MarkerConstraint>& markers;
  const MarkersByName& by_name;
  const std::vector<ImageKeypoints>& keypoints;
  BundleOptions bundle;    // its sigmas a posteriori once estimated
  bool plan_only_control;  // the block is levelled on its ground after each run
};

// The inlier control markers and the observations that passed the screening, adjusted
// together; nothing without options.adjust.
void adjust(const Adjustment& a, const std::vector<std::string>& control_used, Reconstruction& rec,
            MarkerRays& m, BundleSummary& result) {
  if (!a.options.adjust) return;
  const std::set<std::string> used(control_used.begin(), control_used.end());
  std::vector<MarkerConstraint> constraints;
  for (const auto& marker : a.markers) {
    if (used.count(marker.name)) constraints.push_back(marker);
  }
  result = bundle_adjust(a.bundle, rec, a.keypoints, constraints, kept_observations(m.rays));
  if (a.plan_only_control) {
    // The adjustment leaves the tilt to the weak height priors; level it on the
    // ground again and refit in plan (a similarity: reprojections are unchanged).
    fit_markers(rec, m);
    std::vector<Eigen::Vector3d> src, dst;
    for (const auto& name : control_used) {
      const auto& f = m.fits.at(name);
      if (!f.ok) continue;
      src.push_back(f.X);
      dst.push_back(a.by_name.at(name)->position);
    }
    if (src.size() >= 3) transform_reconstruction(level_plan_similarity(rec, src, dst), rec);
  }
  log::debug("georeference: adjustment {} ({} iterations, {:.1f} s, rmse {:.3f} px)", result.message,
             result.iterations, result.seconds, result.rmse_px);
}

struct ObservationSigmas {
  double keypoint_px = 0;
  double marker_px = 0;
};

// What the observations achieved in an adjustment (see estimate_observation_sigmas in
// georeference.hpp); `prior`: the sigmas it used.
ObservationSigmas a_posteriori_sigmas(const BundleSummary& b, const BundleOptions& prior, const Reconstruction& rec,
                                      const MarkerRays& m, const GeoreferenceOptions& options) {
  ObservationSigmas sigmas{prior.keypoint_sigma_px, prior.marker_sigma_px};
  // Keypoints: a posteriori sigma per axis, sum |e|^2 / (2 obs - 3 points - 6 cameras).
  const double n_obs = double(b.observations);
  const double registered = double(std::count_if(rec.images.begin(), rec.images.end(),
                                                 [](const RegisteredImage& im) { return im.registered; }));
  const double dof = 2 * n_obs - 3 * double(rec.points.size()) - 6 * registered;
  if (n_obs > 0 && dof > 0 && std::isfinite(b.rmse_px) && b.rmse_px > 0) {
    sigmas.keypoint_px = std::max(options.min_observation_sigma_px, std::sqrt(b.rmse_px * b.rmse_px * n_obs / dof));
  }
  // Click precision: the agreeing rays about their points, sum e^2 / sum (2 n - 3), over
  // the markers whose rays meet within the clicks alone (no dispersion of their own);
  // a dispersed marker would inflate it for every sharp one.
  double sum2 = 0;
  int redundancy = 0;
  for (const auto& [name, list] : m.rays) {
    const auto& fit = m.fits.at(name);
    if (!fit.ok || fit.dispersion > 0) continue;
    sum2 += fit.rmse_px * fit.rmse_px * fit.agreeing;
    redundancy += 2 * fit.agreeing - 3;
  }
  sigmas.marker_px = sigmas.keypoint_px;
  if (redundancy > 0) sigmas.marker_px = std::max(sigmas.marker_px, std::sqrt(sum2 / redundancy));
  log::info("georeference: observation sigmas a posteriori: keypoints {:.3f} px, marker clicks {:.3f} px "
            "(redundancy {} of the sharp markers)", sigmas.keypoint_px, sigmas.marker_px, redundancy);
  return sigmas;
}

// Once adjusted: fit the markers again at the precision the cameras now have, weigh
// the observations by what they achieved and adjust again.
void adjust_twice(Adjustment& a, const std::vector<std::string>& control_used, Reconstruction& rec, MarkerRays& m,
                  BundleSummary& result) {
  adjust(a, control_used, rec, m, result);
  screen_markers(rec, a.options.duplicate_px, true, m);
  if (a.options.adjust && a.options.estimate_observation_sigmas) {
    const ObservationSigmas sigmas = a_posteriori_sigmas(result, a.bundle, rec, m, a.options);
    a.bundle.keypoint_sigma_px = sigmas.keypoint_px;
    a.bundle.marker_sigma_px = sigmas.marker_px;
    m.options.click_sigma_px = a.bundle.marker_sigma_px;
    fit_markers(rec, m);
  }
  adjust(a, control_used, rec, m, result);
}

struct Residuals {
  std::vector<MarkerResidual> rows;
  std::map<std::string, Eigen::Vector3d> photo_position;  // site frame, usable markers
};

// The photos' side of a marker's row: its fit from the final cameras and each of its
// observations.
void add_photo_residuals(const MarkerConstraint& marker, const std::vector<Ray>& rays, const MarkerRayFit& fit,
                         const Reconstruction& rec, double click_sigma_px, MarkerResidual& row) {
  row.observed = int(rays.size());
  row.images = int(kept_count(rays));
  row.diagnosis = diagnose_marker(fit, rays, rec, click_sigma_px, true);
  if (fit.ok) {
    row.triangulated = true;
    const Eigen::Vector3d d = fit.X - marker.position;
    row.dE = d.x();
    row.dN = d.y();
    row.dZ = d.z();
    row.reprojection_px = fit.rmse_px;
    row.dispersion_m = fit.dispersion;
    row.dispersion_px = fit.mean_footprint > 0 ? fit.dispersion / fit.mean_footprint : 0;
  }
  // The survey seen from each photo; in plan only, at the photo height.
  Eigen::Vector3d survey = marker.position;
  if (!row.height_known && row.triangulated) survey.z() = fit.X.z();
  for (const auto& r : rays) {
    ObservationResidual o;
    o.image = r.image;
    o.image_name = rec.images[r.image].name;
    o.dropped = !r.kept;
    o.sigma_px = r.sigma_px;
    o.to_rays_px = row.triangulated ? pixel_distance(rec, r.image, fit.X, r.pixel) : kNaN;
    o.to_survey_px = pixel_distance(rec, r.image, survey, r.pixel);
    row.observations.push_back(o);
  }
}

// Refits the markers from the final cameras, photos only: a row for every marker given.
Residuals marker_residuals(const GeoreferenceOptions& options, const std::vector<MarkerConstraint>& markers,
                           const std::vector<std::string>& rejected_markers, const Reconstruction& rec,
                           MarkerRays& m) {
  fit_markers(rec, m);
  Residuals res;
  const std::set<std::string> rejected(rejected_markers.begin(), rejected_markers.end());
  for (const auto& marker : markers) {
    MarkerResidual row;
    row.name = marker.name;
    row.role = !marker.control ? MarkerRole::check
                               : (rejected.count(marker.name) ? MarkerRole::rejected : MarkerRole::control);
    row.height_known = !plan_only(marker, options);
    row.distance_misfit_m = kNaN;
    const auto it = m.rays.find(marker.name);
    if (it != m.rays.end()) {
      const MarkerRayFit& fit = m.fits.at(marker.name);
      add_photo_residuals(marker, it->second, fit, rec, m.options.click_sigma_px, row);
      if (fit.ok) res.photo_position[marker.name] = fit.X;
    }
    res.rows.push_back(std::move(row));
  }
  return res;
}

// Leave-one-out: each control marker against the similarity that maps the photo
// positions of the other control markers onto their survey (after the adjustment, so
// the left-out marker still took part in it: a mild optimism, see docs/sfm.md).
void add_leave_one_out(const std::vector<std::string>& control_used, const MarkersByName& by_name,
                       const GeoreferenceOptions& options, Residuals& res) {
  const std::set<std::string> used(control_used.begin(), control_used.end());
  for (auto& row : res.rows) {
    if (row.role == MarkerRole::check || !row.triangulated) continue;
    std::vector<Eigen::Vector3d> src, dst, sigma;
    for (const auto& other : res.rows) {
      if (&other == &row || !used.count(other.name) || !res.photo_position.count(other.name)) continue;
      src.push_back(res.photo_position.at(other.name));
      dst.push_back(by_name.at(other.name)->position);
      sigma.push_back(by_name.at(other.name)->sigma);
    }
    if (src.size() < 3 || std::min(planar_spread_ratio(src), planar_spread_ratio(dst)) < options.min_spread_ratio)
      continue;
    const Similarity3 s = fit_similarity_weighted(src, dst, sigma, options.min_spread_ratio);
    const Eigen::Vector3d d = s.apply(res.photo_position.at(row.name)) - by_name.at(row.name)->position;
    row.loo = true;
    row.loo_dE = d.x();
    row.loo_dN = d.y();
    row.loo_dZ = d.z();
  }
}

struct LeaveOneOutOutlier {
  std::string name;
  double residual_m = 0;
  double limit_m = 0;
  bool height_known = true;
};

// The control marker that the other control markers place farthest beyond its limit,
// relative to that limit; none within their limits.
std::optional<LeaveOneOutOutlier> worst_leave_one_out(const Residuals& res, const MarkersByName& by_name,
                                                      const MarkerRays& m, const GeoreferenceOptions& options) {
  std::optional<LeaveOneOutOutlier> worst;
  double worst_ratio = 1.0;
  for (const auto& row : res.rows) {
    if (row.role != MarkerRole::control || !row.loo) continue;
    const auto& marker = *by_name.at(row.name);
    const auto& fit = m.fits.at(row.name);
    Control c{&marker, res.photo_position.at(row.name), fit.mean_footprint, fit.dispersion, !row.height_known};
    const double r = residual_norm({row.loo_dE, row.loo_dN, row.loo_dZ}, c.plan);
    const double limit = limit_of(c, 1.0, m.options.click_sigma_px, options);
    if (r / limit > worst_ratio) {
      worst_ratio = r / limit;
      worst = LeaveOneOutOutlier{row.name, r, limit, row.height_known};
    }
  }
  return worst;
}

// A control marker that the other control markers place beyond its limit is rejected,
// the worst (relative to its limit) first, and the adjustment redone.
// Only from 5 control markers on: with 4, each leave-one-out fit rests on 3 markers and
// one blunder among them shows on whichever marker is left out (the consensus of
// reject_gross_outliers handles that case).
// Never beyond a third of the usable markers (the consensus rule): rejecting more
// would hide a broad disagreement behind a good fit on the rest.
void reject_after_adjustment(const Adjustment& a, std::size_t n_usable, Reconstruction& rec, MarkerRays& m,
                             GeoreferenceSummary& summary, std::vector<Blunder>& blunders, Residuals& res) {
  const GeoreferenceOptions& options = a.options;
  for (int round = 0; round < options.max_rejection_rounds && summary.control_used.size() >= 5 &&
                      is_agreement(summary.control_used.size() - 1, n_usable);
       ++round) {
    const auto worst = worst_leave_one_out(res, a.by_name, m, options);
    if (!worst) break;
    std::vector<std::string> rest;
    for (const auto& n : summary.control_used) {
      if (n != worst->name) rest.push_back(n);
    }
    std::vector<Eigen::Vector3d> rest_site;
    for (const auto& n : rest) rest_site.push_back(a.by_name.at(n)->position);
    if (planar_spread_ratio(rest_site) < options.min_spread_ratio) break;
    summary.control_used = rest;
    summary.rejected.push_back(worst->name);
    blunders.push_back({worst->name, "", worst->residual_m, "m",
                        fmt::format("{:.3f} m {}from the other control markers after the adjustment "
                                    "(leave-one-out, limit {:.3f} m): survey and photos disagree",
                                    worst->residual_m, worst->height_known ? "" : "in plan ", worst->limit_m)});
    adjust(a, summary.control_used, rec, m, summary.bundle);
    res = marker_residuals(options, a.markers, summary.rejected, rec, m);
    add_leave_one_out(summary.control_used, a.by_name, options, res);
  }
}

// Distances between markers, survey against photos: independent of any similarity.
void add_distance_misfits(const MarkersByName& by_name, Residuals& res) {
  for (auto& row : res.rows) {
    if (!row.triangulated) continue;
    std::vector<double> misfit;
    for (const auto& other : res.rows) {
      if (&other == &row || !other.triangulated) continue;
      const bool plan = !row.height_known || !other.height_known;
      const double photo =
          residual_norm(res.photo_position.at(row.name) - res.photo_position.at(other.name), plan);
      const double survey = residual_norm(by_name.at(row.name)->position - by_name.at(other.name)->position, plan);
      misfit.push_back(std::abs(photo - survey));
    }
    row.distance_misfit_m = median(misfit);
  }
}

// Every observation left out, named: clicks on another marker's target, those that
// disagree with their marker's other rays in the final fit; then the markers not used
// and the control markers rejected.
std::vector<Blunder> all_blunders(const MarkerRays& m, const Reconstruction& rec,
                                  const std::vector<Blunder>& marker_blunders, const std::vector<Blunder>& rejected) {
  std::vector<Blunder> all = m.duplicates;
  for (const auto& [name, list] : m.rays) {
    const auto& fit = m.fits.at(name);
    if (fit.agreeing < 2) continue;  // the marker as a whole is named in marker_blunders
    for (const auto& r : list) {
      if (r.kept || !r.excluded.empty()) continue;
      all.push_back({name, rec.images[r.image].name, r.error_px, "px",
                     fmt::format("{:.1f} px from where its {} agreeing rays meet (this photo is "
                                 "expected within {:.1f} px): a wrong click or a different point",
                                 r.error_px, fit.agreeing,
                                 std::max(m.options.agree_factor * r.sigma_px, m.options.min_gate_px))});
    }
  }
  all.insert(all.end(), marker_blunders.begin(), marker_blunders.end());
  all.insert(all.end(), rejected.begin(), rejected.end());
  return all;
}

// Findings about the block as a whole, each logged as a warning.
std::vector<std::string> diagnose_block(const Residuals& res, const MarkersByName& by_name,
                                        const std::vector<Control>& usable, double scale, const MarkerRays& m,
                                        const Reconstruction& rec) {
  std::vector<std::string> diagnosis;
  {
    // "Reaches the limit": three times the markers' median photo precision (the block's
    // own, not the survey's), and at least a centimetre so survey noise is not taken
    // for a dome.
    std::vector<double> precision;
    for (const auto& c : usable) {
      precision.push_back(std::hypot(m.options.click_sigma_px * c.footprint, c.dispersion) * scale);
    }
    if (auto bent = diagnose_bending(res.rows, by_name, std::max(kMinBendingM, 3 * median(precision)))) {
      diagnosis.push_back(*bent);
      log::warn("georeference: {}", *bent);
    }
  }
  if (auto lens = diagnose_lens(m.rays, rec)) {
    diagnosis.push_back(*lens);
    log::warn("georeference: {}", *lens);
  }
  for (const auto& photo : diagnose_misplaced_photos(m.rays, m.fits, rec)) {
    diagnosis.push_back(photo);
    log::warn("georeference: {}", photo);
  }
  return diagnosis;
}

// The figures of the summary from its residual table, and its message.
void summarise(GeoreferenceSummary& summary) {
  summary.control = rmse_of(summary.residuals, MarkerRole::control, false);
  summary.check = rmse_of(summary.residuals, MarkerRole::check, false);
  summary.leave_one_out = rmse_of(summary.residuals, MarkerRole::control, true);
  summary.georeferenced = true;
  const auto dropped_observations =
      std::count_if(summary.blunders.begin(), summary.blunders.end(), [](const Blunder& b) { return !b.image.empty(); });
  summary.message = fmt::format(
      "georeferenced on {} control markers ({} rejected, {} observations left out); control RMSE "
      "{:.4f} m (leave-one-out {:.4f} m), check RMSE {:.4f} m over {} check marker(s){}",
      summary.control_used.size(), summary.rejected.size(), dropped_observations, summary.control.xyz,
      summary.leave_one_out.xyz, summary.check.xyz, summary.check.markers,
      summary.control.markers_z < summary.control.markers ? " (heights unknown for some: plan figures only for them)" : "");
}

}  // namespace

std::optional<Eigen::Vector3d> up_from_cameras(const Reconstruction& rec) {
  // Photos of a trench look down at it: the sum of the optical axes points down
  // (a ring of oblique photos cancels sideways). Below this share of the cameras'
  // count the views point every way (an object photographed all round, a room) and
  // say nothing about up.
  constexpr double kMinAgreement = 0.3;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int n = 0;
  for (const auto& im : rec.images) {
    if (!im.registered) continue;
    sum += im.pose.R.row(2).transpose();  // the optical axis (camera +z) in the frame
    ++n;
  }
  if (n == 0 || sum.norm() < kMinAgreement * n) return std::nullopt;
  return Eigen::Vector3d(-sum.normalized());
}

GeoreferenceSummary keep_arbitrary_frame(Reconstruction& rec) {
  rec.georeferenced = false;
  GeoreferenceSummary s;
  s.georeferenced = false;
  // The alignment's frame is the first photo's: a plan would show the trench on its
  // side or upside down. Turned so that the cameras' common viewing direction is
  // down (-Z); the scale and the heading stay arbitrary.
  const auto up = up_from_cameras(rec);
  if (up) {
    Similarity3 level;
    level.R = Eigen::Quaterniond::FromTwoVectors(*up, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    transform_reconstruction(level, rec);
  }
  s.message = fmt::format("no control markers: the layer stays in an arbitrary local frame at an arbitrary scale{}",
                          up ? ", turned so that the cameras look down" : " (its up is unknown: the cameras look every way)");
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
  const MarkersByName by_name = index_markers(markers);
  warn_of_raw_crs_coordinates(markers);

  // 1. Fit every marker from its rays in the reconstruction frame (pixels do not depend
  // on the frame, and the dispersion is relative to the viewing distance).
  MarkerRays marker_rays = collect_marker_rays(options, observations, by_name, rec);
  screen_markers(rec, options.duplicate_px, false, marker_rays);

  // 2. The usable control markers, in the reconstruction frame.
  const ControlSet control = select_control(options, markers, marker_rays, rec);
  summary.unusable = control.unusable;
  require_control_geometry(options, control);

  // 3. Robust similarity.
  const ControlInliers chosen = reject_gross_outliers(control.usable, marker_rays.options.click_sigma_px, options);
  summary.rejected = chosen.rejected;
  std::vector<Blunder> rejected = chosen.blunders;  // control markers rejected against the survey
  for (int i : chosen.inliers) summary.control_used.push_back(control.usable[i].m->name);
  const bool plan_only_control =
      std::all_of(chosen.inliers.begin(), chosen.inliers.end(), [&](int i) { return control.usable[i].plan; });
  summary.similarity = control_similarity(rec, control.usable, chosen.inliers, plan_only_control, options);

  // 4. Into the site frame.
  transform_reconstruction(summary.similarity, rec);
  rec.georeferenced = true;

  // 5. Combined adjustment of photos and survey. The free block's reprojection RMSE is
  // the yardstick of a survey that bends it (refuse_foreign_photos).
  const double rmse_free_px = reprojection_rmse_px(rec, keypoints);
  Adjustment adjustment{options, markers, by_name, keypoints, options.bundle, plan_only_control};
  adjust_twice(adjustment, summary.control_used, rec, marker_rays, summary.bundle);
  summary.keypoint_sigma_px = adjustment.bundle.keypoint_sigma_px;
  summary.marker_sigma_px = adjustment.bundle.marker_sigma_px;

  // 6. Residuals from the final cameras, photos only; a control marker the others
  // reject there is rejected and the adjustment redone.
  Residuals residuals = marker_residuals(options, markers, summary.rejected, rec, marker_rays);
  add_leave_one_out(summary.control_used, by_name, options, residuals);
  reject_after_adjustment(adjustment, control.usable.size(), rec, marker_rays, summary, rejected, residuals);
  for (const auto& row : residuals.rows) {
    if (row.role == MarkerRole::check && !row.triangulated) summary.unusable.push_back(row.name);
  }
  add_distance_misfits(by_name, residuals);
  std::vector<Blunder> blunders = all_blunders(marker_rays, rec, control.blunders, rejected);
  for (const auto& b : blunders) {
    log::debug("georeference: dropped {}{}: {}", b.marker, b.image.empty() ? "" : " in " + b.image, b.reason);
  }
  for (const auto& row : residuals.rows) {
    if (!row.diagnosis.empty()) log::warn("georeference: marker {}: {}", row.name, row.diagnosis);
  }
  summary.diagnosis = diagnose_block(residuals, by_name, control.usable, summary.similarity.scale, marker_rays, rec);
  {
    std::vector<std::string> scattered;  // clicked in 2 or more photos, rays not one point
    for (const auto& b : control.blunders) scattered.push_back(b.marker);
    refuse_foreign_photos(residuals.rows, by_name, control.names, scattered, marker_rays.options.click_sigma_px,
                          rmse_free_px, options.adjust ? summary.bundle.rmse_px : 0.0, options);
  }
  summary.residuals = std::move(residuals.rows);
  summary.blunders = std::move(blunders);
  summary.seconds = clock.seconds();
  summarise(summary);
  return summary;
}

}  // namespace strata
