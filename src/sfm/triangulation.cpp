#include "sfm/triangulation.hpp"

#include "core/error.hpp"
#include "sfm/bundle_problem.hpp"
#include "sfm/cost_functions.hpp"

#include <ceres/ceres.h>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <limits>

namespace strata {

Eigen::Vector3d triangulate_dlt(const std::vector<Pose>& poses,
                                const std::vector<Eigen::Vector2d>& normalised) {
  STRATA_CHECK(poses.size() == normalised.size() && poses.size() >= 2);
  Eigen::MatrixXd A(2 * poses.size(), 4);
  for (std::size_t i = 0; i < poses.size(); ++i) {
    Eigen::Matrix<double, 3, 4> P;
    P.leftCols<3>() = poses[i].R;
    P.col(3) = poses[i].t;
    // Rows normalised so every view weighs about the same.
    Eigen::RowVector4d r1 = normalised[i].x() * P.row(2) - P.row(0);
    Eigen::RowVector4d r2 = normalised[i].y() * P.row(2) - P.row(1);
    A.row(2 * i) = r1 / std::max(r1.norm(), 1e-12);
    A.row(2 * i + 1) = r2 / std::max(r2.norm(), 1e-12);
  }
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d h = svd.matrixV().col(3);
  if (std::abs(h(3)) < 1e-15) return Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  return h.head<3>() / h(3);
}

double max_triangulation_angle_deg(const Eigen::Vector3d& X,
                                   const std::vector<Eigen::Vector3d>& centres) {
  double best_cos = 1.0;
  for (std::size_t i = 0; i < centres.size(); ++i) {
    const Eigen::Vector3d a = (X - centres[i]).normalized();
    for (std::size_t j = i + 1; j < centres.size(); ++j) {
      best_cos = std::min(best_cos, a.dot((X - centres[j]).normalized()));
    }
  }
  return std::acos(std::clamp(best_cos, -1.0, 1.0)) * 180.0 / M_PI;
}

TriangulationResult triangulate_views(const std::vector<Camera>& cameras,
                                      const std::vector<Eigen::Vector2d>& pixels,
                                      const TriangulationOptions& options) {
  STRATA_CHECK(cameras.size() == pixels.size());
  TriangulationResult result;
  result.views = int(cameras.size());
  if (cameras.size() < 2) return result;
  std::vector<Pose> poses;
  std::vector<Eigen::Vector2d> xn;
  std::vector<Eigen::Vector3d> centres;
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    poses.push_back(cameras[i].pose);
    xn.push_back(cameras[i].intrinsics.to_normalised(pixels[i]));
    centres.push_back(cameras[i].pose.centre());
  }
  Eigen::Vector3d X = triangulate_dlt(poses, xn);
  if (!X.allFinite()) return result;
  for (const auto& p : poses) {
    if (p.to_camera(X).z() <= 0) return result;
  }
  if (options.refine) {
    // Maximum-likelihood point for fixed cameras: minimise the reprojection error.
    using namespace sfm_detail;
    std::vector<IntrinsicsBlock> intr;
    std::vector<std::array<double, kPoseSize>> pose;
    for (const auto& c : cameras) {
      intr.push_back(to_block(c.intrinsics));
      pose.push_back(to_block(c.pose));
    }
    ceres::Problem problem;
    double point[3] = {X.x(), X.y(), X.z()};
    for (std::size_t i = 0; i < cameras.size(); ++i) {
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<ReprojectionCost, 2, kPoseSize, kIntrinsicsSize, 3>(
              new ReprojectionCost(pixels[i], 1.0, cameras[i].intrinsics.model)),
          nullptr, pose[i].data(), intr[i].data(), point);
      problem.SetParameterBlockConstant(pose[i].data());
      problem.SetParameterBlockConstant(intr[i].data());
    }
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.logging_type = ceres::SILENT;
    so.max_num_iterations = 20;
    so.function_tolerance = 1e-14;
    so.parameter_tolerance = 1e-14;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    const Eigen::Vector3d refined(point[0], point[1], point[2]);
    if (refined.allFinite()) X = refined;
  }
  result.X = X;
  result.max_angle_deg = max_triangulation_angle_deg(X, centres);
  double sum2 = 0;
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const auto proj = cameras[i].project(X);
    if (!proj) {  // behind a camera: no valid point
      result.max_error_px = result.rmse_px = std::numeric_limits<double>::infinity();
      return result;
    }
    const double e = (*proj - pixels[i]).norm();
    sum2 += e * e;
    result.max_error_px = std::max(result.max_error_px, e);
  }
  result.rmse_px = std::sqrt(sum2 / double(cameras.size()));
  result.ok = result.max_angle_deg >= options.min_angle_deg &&
              result.max_error_px <= options.max_error_px;
  return result;
}

}  // namespace strata
