#pragma once
// Multi-view triangulation of one point from calibrated cameras.
#include "geometry/camera.hpp"

#include <Eigen/Core>

#include <vector>

namespace strata {

struct TriangulationOptions {
  // degrees: the largest angle between two rays must reach this, otherwise the
  // depth is unreliable (error grows like 1 / sin(angle)).
  double min_angle_deg = 1.5;
  // pixels: every ray must reproject within this distance.
  double max_error_px = 4.0;
  // Refine the linear solution by minimising the reprojection error (Ceres).
  bool refine = true;
};

struct TriangulationResult {
  bool ok = false;
  Eigen::Vector3d X = Eigen::Vector3d::Zero();  // metres, the cameras' frame
  double max_angle_deg = 0;                     // largest angle between two rays
  double rmse_px = 0;                           // RMS reprojection error over the views
  double max_error_px = 0;
  int views = 0;
};

// Linear triangulation (DLT, Hartley & Zisserman 2004, sec. 12.2) from undistorted
// normalised coordinates: each view adds x (P3 X) - (P1 X) = 0, y (P3 X) - (P2 X) = 0.
Eigen::Vector3d triangulate_dlt(const std::vector<Pose>& poses,
                                const std::vector<Eigen::Vector2d>& normalised);

// Largest angle between the rays from `centres` to X, degrees.
double max_triangulation_angle_deg(const Eigen::Vector3d& X,
                                   const std::vector<Eigen::Vector3d>& centres);

// Triangulates from >= 2 views (pixels of the original photos), then checks
// positive depth, angle and reprojection error; `ok` tells whether all passed.
TriangulationResult triangulate_views(const std::vector<Camera>& cameras,
                                      const std::vector<Eigen::Vector2d>& pixels,
                                      const TriangulationOptions& options);

}  // namespace strata
