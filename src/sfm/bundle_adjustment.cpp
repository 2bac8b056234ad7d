#include "sfm/bundle_adjustment.hpp"

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/resources.hpp"
#include "sfm/bundle_problem.hpp"
#include "sfm/triangulation.hpp"

#include <ceres/ceres.h>
#include <glog/logging.h>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>

namespace strata {
namespace {

// Ceres reports through glog, whose warnings (e.g. "Linear solver failure ... dense
// Cholesky" when a Levenberg-Marquardt step is retried with more damping, which the
// solver handles itself) would interleave with strata's own messages and progress
// bars as unformatted lines. Only glog errors and above reach the terminal; the
// outcome of every solve is judged from its summary here and reported by strata.
[[maybe_unused]] const bool kSolverLogQuiet = [] {
  FLAGS_minloglevel = std::max(FLAGS_minloglevel, static_cast<std::int32_t>(google::GLOG_ERROR));
  return true;
}();

}  // namespace


void BundleOptions::validate() const {
  auto positive = [](double v, const char* name) {
    if (!(v > 0) || !std::isfinite(v)) {
      throw InputError(fmt::format("bundle adjustment option {} must be > 0, got {}", name, v));
    }
  };
  positive(loss_scale_px, "loss_scale_px");
  positive(keypoint_sigma_px, "keypoint_sigma_px");
  positive(marker_sigma_px, "marker_sigma_px");
  positive(function_tolerance, "function_tolerance");
  positive(gradient_tolerance, "gradient_tolerance");
  positive(parameter_tolerance, "parameter_tolerance");
  if (max_iterations < 1) {
    throw InputError(fmt::format("bundle adjustment option max_iterations must be >= 1, got {}",
                                 max_iterations));
  }
}

namespace sfm_detail {

IntrinsicsBlock to_block(const Intrinsics& k) {
  IntrinsicsBlock b{};
  b[kFocal] = k.fx;
  b[kCx] = k.cx;
  b[kCy] = k.cy;
  b[kK1] = k.k1;
  b[kK2] = k.k2;
  b[kAspect] = k.fx != 0 ? k.fy / k.fx : 1.0;
  // Only the coefficients of the model: the others are held constant at zero, so a
  // stray value in an unused field cannot enter the projection.
  const bool brown = k.model == CameraModel::brown, fisheye = k.model == CameraModel::fisheye;
  b[kK3] = brown || fisheye ? k.k3 : 0.0;
  b[kK4] = fisheye ? k.k4 : 0.0;
  b[kP1] = brown ? k.p1 : 0.0;
  b[kP2] = brown ? k.p2 : 0.0;
  return b;
}

void add_group(BaProblem& problem, const Intrinsics& k, bool calibration_fixed) {
  problem.intrinsics.push_back(to_block(k));
  problem.models.push_back(k.model);
  problem.intrinsics_fixed.push_back(calibration_fixed ? 1 : 0);
}

std::vector<int> constant_intrinsics(const IntrinsicsRefinement& refine, CameraModel model) {
  const bool brown = model == CameraModel::brown, fisheye = model == CameraModel::fisheye;
  std::vector<int> fixed;
  if (!refine.focal) fixed.push_back(kFocal);
  if (!refine.principal_point) {
    fixed.push_back(kCx);
    fixed.push_back(kCy);
  }
  if (!refine.k1) fixed.push_back(kK1);
  if (!refine.k2) fixed.push_back(kK2);
  if (!refine.aspect_ratio) fixed.push_back(kAspect);
  if (!refine.k3 || !(brown || fisheye)) fixed.push_back(kK3);
  if (!refine.k4 || !fisheye) fixed.push_back(kK4);
  if (!refine.tangential || !brown) {
    fixed.push_back(kP1);
    fixed.push_back(kP2);
  }
  std::sort(fixed.begin(), fixed.end());
  return fixed;
}

void from_block(const IntrinsicsBlock& b, Intrinsics& k) {
  k.fx = b[kFocal];
  k.fy = b[kFocal] * b[kAspect];
  k.cx = b[kCx];
  k.cy = b[kCy];
  k.k1 = b[kK1];
  k.k2 = b[kK2];
  k.k3 = b[kK3];
  k.k4 = b[kK4];
  k.p1 = b[kP1];
  k.p2 = b[kP2];
}

std::array<double, kPoseSize> to_block(const Pose& pose) {
  const Eigen::AngleAxisd aa(pose.R);
  const Eigen::Vector3d w = aa.axis() * aa.angle();
  return {w.x(), w.y(), w.z(), pose.t.x(), pose.t.y(), pose.t.z()};
}

Pose pose_from_block(const std::array<double, kPoseSize>& b) {
  Pose pose;
  const Eigen::Vector3d w(b[0], b[1], b[2]);
  const double angle = w.norm();
  pose.R = angle < 1e-15 ? Eigen::Matrix3d::Identity()
                         : Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
  pose.t = Eigen::Vector3d(b[3], b[4], b[5]);
  return pose;
}

void set_gauge(BaProblem& problem, int a, int b) {
  problem.gauge_camera = a;
  problem.gauge_scale_camera = b;
  const Pose pa = pose_from_block(problem.cameras[a].pose);
  const Pose pb = pose_from_block(problem.cameras[b].pose);
  // Scaling by s about Ca changes t_b by -(s - 1) Rb (Cb - Ca): fix its largest entry.
  const Eigen::Vector3d d = pb.R * (pb.centre() - pa.centre());
  d.cwiseAbs().maxCoeff(&problem.gauge_scale_axis);
}

double reprojection_error_px(const BaProblem& problem, const BaObservation& obs) {
  const auto& cam = problem.cameras[obs.camera];
  const ReprojectionCost cost(obs.pixel, 1.0, problem.models[cam.group]);
  double r[2];
  if (!cost(cam.pose.data(), problem.intrinsics[cam.group].data(), problem.points[obs.point].data(),
            r)) {
    return std::numeric_limits<double>::infinity();
  }
  return std::hypot(r[0], r[1]);
}

namespace {

std::unique_ptr<ceres::LossFunction> make_loss(RobustLoss loss, double scale) {
  switch (loss) {
    case RobustLoss::none:
      return nullptr;
    case RobustLoss::huber:
      return std::make_unique<ceres::HuberLoss>(scale);
    case RobustLoss::cauchy:
      return std::make_unique<ceres::CauchyLoss>(scale);
  }
  return nullptr;
}

// The blocks that some residual reads: only those can be held constant.
struct UsedBlocks {
  std::vector<char> camera, group, point;
};

// A reprojection residual per observation that moves something, a prior per control
// marker; counts them in `summary`.
UsedBlocks add_residuals(const BundleOptions& options, BaProblem& problem, ceres::LossFunction* keypoint_loss,
                         ceres::LossFunction* marker_loss, ceres::Problem& ceres_problem, BundleSummary& summary) {
  UsedBlocks used{std::vector<char>(problem.cameras.size(), 0), std::vector<char>(problem.intrinsics.size(), 0),
                  std::vector<char>(problem.points.size(), 0)};
  for (const auto& obs : problem.observations) {
    auto& cam = problem.cameras[obs.camera];
    if (!cam.variable && !problem.point_variable[obs.point]) continue;
    const double sigma = obs.sigma_px > 0 ? obs.sigma_px
                         : obs.marker     ? options.marker_sigma_px
                                          : options.keypoint_sigma_px;
    auto* cost = new ceres::AutoDiffCostFunction<ReprojectionCost, 2, kPoseSize, kIntrinsicsSize, 3>(
        new ReprojectionCost(obs.pixel, sigma, problem.models[cam.group]));
    ceres_problem.AddResidualBlock(cost, obs.marker ? marker_loss : keypoint_loss,
                                   cam.pose.data(), problem.intrinsics[cam.group].data(),
                                   problem.points[obs.point].data());
    used.camera[obs.camera] = 1;
    used.group[cam.group] = 1;
    used.point[obs.point] = 1;
    (obs.marker ? summary.marker_observations : summary.observations)++;
  }
  for (const auto& prior : problem.priors) {
    auto* cost = new ceres::AutoDiffCostFunction<MarkerPriorCost, 3, 3>(
        new MarkerPriorCost(prior.position, prior.sigma));
    ceres_problem.AddResidualBlock(cost, nullptr, problem.points[prior.point].data());
    used.point[prior.point] = 1;
    ++summary.control_markers;
  }
  return used;
}

// Constant blocks: fixed cameras, fixed points, intrinsics as options say.
void hold_constant_blocks(const BundleOptions& options, BaProblem& problem, const UsedBlocks& used,
                          ceres::Problem& ceres_problem) {
  bool any_variable_camera = false;
  for (std::size_t c = 0; c < problem.cameras.size(); ++c) {
    if (!used.camera[c]) continue;
    auto& cam = problem.cameras[c];
    if (!cam.variable) {
      ceres_problem.SetParameterBlockConstant(cam.pose.data());
    } else {
      any_variable_camera = true;
    }
  }
  for (std::size_t p = 0; p < problem.points.size(); ++p) {
    if (used.point[p] && !problem.point_variable[p]) {
      ceres_problem.SetParameterBlockConstant(problem.points[p].data());
    }
  }
  for (std::size_t g = 0; g < problem.intrinsics.size(); ++g) {
    if (!used.group[g]) continue;
    double* block = problem.intrinsics[g].data();
    const bool fixed = g < problem.intrinsics_fixed.size() && problem.intrinsics_fixed[g];
    const std::vector<int> constant = constant_intrinsics(options.refine, problem.models[g]);
    if (fixed || !problem.refine_intrinsics || !any_variable_camera ||
        constant.size() == std::size_t(kIntrinsicsSize)) {
      ceres_problem.SetParameterBlockConstant(block);
    } else if (!constant.empty()) {
      ceres_problem.SetManifold(block, new ceres::SubsetManifold(kIntrinsicsSize, constant));
    }
  }
}

// Datum of an unreferenced problem.
void fix_gauge(BaProblem& problem, const UsedBlocks& used, ceres::Problem& ceres_problem, BundleSummary& summary) {
  if (problem.gauge_camera >= 0 && used.camera[problem.gauge_camera] &&
      problem.cameras[problem.gauge_camera].variable) {
    ceres_problem.SetParameterBlockConstant(problem.cameras[problem.gauge_camera].pose.data());
    summary.gauge_fixed = true;
  }
  if (problem.gauge_scale_camera >= 0 && used.camera[problem.gauge_scale_camera] &&
      problem.cameras[problem.gauge_scale_camera].variable) {
    ceres_problem.SetManifold(problem.cameras[problem.gauge_scale_camera].pose.data(),
                              new ceres::SubsetManifold(kPoseSize, {3 + problem.gauge_scale_axis}));
    summary.gauge_fixed = true;
  }
}

ceres::Solver::Options make_solver_options(const BundleOptions& options, const UsedBlocks& used) {
  ceres::Solver::Options solver_options;
  const std::size_t n_cameras =
      std::size_t(std::count(used.camera.begin(), used.camera.end(), char(1)));
  // The reduced camera system is small for a layer (tens of photos): dense Schur is
  // fastest there (COLMAP uses the same threshold idea).
  if (n_cameras <= 60) {
    solver_options.linear_solver_type = ceres::DENSE_SCHUR;
  } else if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)) {
    solver_options.linear_solver_type = ceres::SPARSE_SCHUR;
  } else {
    solver_options.linear_solver_type = ceres::ITERATIVE_SCHUR;
    solver_options.preconditioner_type = ceres::SCHUR_JACOBI;
  }
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.gradient_tolerance = options.gradient_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  // One thread: Ceres sums the residuals and
  // assembles the reduced system per thread, and the order of those floating-point
  // sums moved camera centres by 1e-14 m between identical runs, which changed the
  // products' checksums. Measured on a 14-photo layer: the sparse
  // stage took 6.0 s with one thread against 6.1 s with two; feature extraction and
  // matching, not the adjustment, use the cores.
  solver_options.num_threads = 1;
  solver_options.logging_type = ceres::SILENT;
  solver_options.minimizer_progress_to_stdout = false;
  return solver_options;
}

// RMS reprojection error of the keypoint observations, pixels.
double keypoint_rmse_px(const BaProblem& problem) {
  double sum2 = 0;
  std::size_t n = 0;
  for (const auto& obs : problem.observations) {
    if (obs.marker) continue;
    const double e = reprojection_error_px(problem, obs);
    if (!std::isfinite(e)) continue;
    sum2 += e * e;
    ++n;
  }
  return n ? std::sqrt(sum2 / double(n)) : 0.0;
}

}  // namespace

BundleSummary solve_bundle(const BundleOptions& options, BaProblem& problem) {
  Stopwatch clock;
  BundleSummary summary;
  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem ceres_problem(problem_options);

  // Residuals are in units of sigma, so the loss scale is too.
  const auto keypoint_loss =
      make_loss(options.loss, options.loss_scale_px / options.keypoint_sigma_px);
  const auto marker_loss =
      make_loss(options.marker_loss, options.loss_scale_px / options.marker_sigma_px);

  const UsedBlocks used = add_residuals(options, problem, keypoint_loss.get(), marker_loss.get(), ceres_problem, summary);
  if (summary.observations + summary.marker_observations == 0) {
    summary.message = "nothing to adjust";
    return summary;
  }
  hold_constant_blocks(options, problem, used, ceres_problem);
  fix_gauge(problem, used, ceres_problem, summary);

  ceres::Solver::Summary ceres_summary;
  ceres::Solve(make_solver_options(options, used), &ceres_problem, &ceres_summary);

  summary.iterations = int(ceres_summary.iterations.size());
  summary.converged = ceres_summary.termination_type == ceres::CONVERGENCE;
  summary.initial_cost = ceres_summary.initial_cost;
  summary.final_cost = ceres_summary.final_cost;
  summary.message = ceres_summary.BriefReport();
  summary.rmse_px = keypoint_rmse_px(problem);
  summary.seconds = clock.seconds();
  return summary;
}

}  // namespace sfm_detail

BundleSummary bundle_adjust(const BundleOptions& options, Reconstruction& rec,
                            const std::vector<ImageKeypoints>& keypoints,
                            const std::vector<MarkerConstraint>& markers,
                            const std::vector<MarkerObservation>& observations) {
  using namespace sfm_detail;
  options.validate();
  STRATA_CHECK(keypoints.size() == rec.images.size(), "{} keypoint sets for {} images",
               keypoints.size(), rec.images.size());

  BaProblem problem;
  for (const auto& g : rec.groups) add_group(problem, g.intrinsics, g.calibration_fixed);
  std::vector<int> camera_of_image(rec.images.size(), -1);
  for (std::size_t i = 0; i < rec.images.size(); ++i) {
    const auto& im = rec.images[i];
    if (!im.registered) continue;
    STRATA_CHECK(im.group >= 0 && std::size_t(im.group) < rec.groups.size());
    BaCamera cam;
    cam.pose = to_block(im.pose);
    cam.group = im.group;
    camera_of_image[i] = int(problem.cameras.size());
    problem.cameras.push_back(cam);
  }
  for (std::size_t p = 0; p < rec.points.size(); ++p) {
    problem.points.push_back(rec.points[p].X);
    problem.point_variable.push_back(1);
    for (const auto& el : rec.points[p].track) {
      STRATA_CHECK(el.image >= 0 && std::size_t(el.image) < rec.images.size());
      const int cam = camera_of_image[el.image];
      if (cam < 0) continue;
      const auto& kps = keypoints[el.image].points;
      STRATA_CHECK(el.keypoint >= 0 && std::size_t(el.keypoint) < kps.size());
      problem.observations.push_back({cam, int(p), kps[el.keypoint], false});
    }
  }

  // Control markers: a 3D point each, observed in images and tied to the survey.
  std::map<std::string, std::vector<const MarkerObservation*>> seen;
  for (const auto& o : observations) {
    if (o.image >= 0 && std::size_t(o.image) < rec.images.size() && camera_of_image[o.image] >= 0) {
      seen[o.marker].push_back(&o);
    }
  }
  for (const auto& m : markers) {
    if (!m.control) continue;
    const auto it = seen.find(m.name);
    if (it == seen.end()) continue;
    if (!(m.sigma.minCoeff() > 0)) {
      throw InputError(fmt::format("marker {}: sigma must be > 0 on every axis", m.name));
    }
    // Start from the photo triangulation (reconstruction frame) when there is one;
    // otherwise from the survey (the frame must already be georeferenced).
    Eigen::Vector3d start = m.position;
    if (it->second.size() >= 2) {
      std::vector<Camera> cams;
      std::vector<Eigen::Vector2d> px;
      for (const auto* o : it->second) {
        cams.push_back({rec.groups[rec.images[o->image].group].intrinsics, rec.images[o->image].pose});
        px.push_back(o->pixel);
      }
      const auto tri = triangulate_views(cams, px, TriangulationOptions{});
      if (tri.ok) start = tri.X;
    }
    const int point = int(problem.points.size());
    problem.points.push_back(start);
    problem.point_variable.push_back(1);
    for (const auto* o : it->second) {
      problem.observations.push_back({camera_of_image[o->image], point, o->pixel, true, o->sigma_px});
    }
    problem.priors.push_back({point, m.position, m.sigma});
  }

  if (problem.priors.empty() && problem.cameras.size() >= 2) {
    // Arbitrary frame: fix the datum on the first two registered images.
    set_gauge(problem, 0, 1);
  }

  const BundleSummary summary = solve_bundle(options, problem);

  for (std::size_t g = 0; g < rec.groups.size(); ++g) {
    // A fixed calibration is not read back: the block's aspect ratio (fy / fx) would
    // round fy, and a fixed calibration must come out bit-identical.
    if (rec.groups[g].calibration_fixed) continue;
    from_block(problem.intrinsics[g], rec.groups[g].intrinsics);
  }
  for (std::size_t i = 0; i < rec.images.size(); ++i) {
    const int c = camera_of_image[i];
    if (c < 0) continue;
    rec.images[i].pose = pose_from_block(problem.cameras[c].pose);
  }
  for (std::size_t p = 0; p < rec.points.size(); ++p) {
    rec.points[p].X = problem.points[p];
  }
  // Refresh the per-point mean reprojection error.
  std::vector<double> sum(rec.points.size(), 0.0);
  std::vector<int> count(rec.points.size(), 0);
  for (const auto& obs : problem.observations) {
    if (obs.marker) continue;
    sum[obs.point] += reprojection_error_px(problem, obs);
    ++count[obs.point];
  }
  for (std::size_t p = 0; p < rec.points.size(); ++p) {
    rec.points[p].error_px = count[p] ? sum[p] / count[p] : 0.0;
  }
  return summary;
}

}  // namespace strata
