#pragma once
// The camera model shared by every stage (synthetic renderer, SfM, dense, products).
//
// Conventions (documented in docs/architecture.md):
//  - world coordinates are the site frame: site CRS (E, N, height) minus the
//    site origin, in metres, double precision; right-handed, z up.
//  - pose: world-to-camera rotation R and translation t, X_cam = R * X_world + t;
//    camera centre C = -R^T t. The camera looks along +z_cam, x_cam to the right of
//    the image, y_cam down the image (OpenCV / COLMAP convention).
//  - pixels: (0, 0) is the centre of the top-left pixel (OpenCV convention);
//    COLMAP's convention puts the corner there, so its principal point is ours + 0.5.
//  - intrinsics: focal lengths fx, fy and principal point cx, cy in pixels, and a lens
//    model on normalised coordinates x = X_c.xy / X_c.z (docs/cameras.md):
//      radial   x_d = x (1 + k1 r^2 + k2 r^4)  (Brown 1966; COLMAP's 'RADIAL' with fx, fy)
//      brown    x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + tangential(p1, p2)
//               (Brown 1971 / OpenCV's 5-coefficient model; COLMAP 'FULL_OPENCV' subset)
//      fisheye  equidistant: theta = atan(r), theta_d = theta (1 + k1 theta^2 + k2 theta^4
//               + k3 theta^6 + k4 theta^8), x_d = x theta_d / r (Kannala & Brandt 2006;
//               OpenCV's cv::fisheye, COLMAP 'OPENCV_FISHEYE')
#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>
#include <string>

namespace strata {

enum class CameraModel { radial, brown, fisheye };
const char* to_string(CameraModel model);
// "radial" | "brown" | "fisheye"; empty when the name is unknown.
std::optional<CameraModel> camera_model_from_string(const std::string& name);

struct Intrinsics {
  int width = 0;   // pixels
  int height = 0;  // pixels
  double fx = 0;   // pixels
  double fy = 0;   // pixels
  double cx = 0;   // pixels
  double cy = 0;   // pixels
  double k1 = 0;   // radial distortion coefficients, unitless (meaning per model, above)
  double k2 = 0;
  double k3 = 0;   // brown, fisheye
  double k4 = 0;   // fisheye only
  double p1 = 0;   // tangential (decentring) distortion, brown only, unitless
  double p2 = 0;
  // Last, so that brace initialisers {w, h, fx, fy, cx, cy, k1, k2} keep their meaning.
  CameraModel model = CameraModel::radial;

  // Applies the lens model to normalised coordinates.
  Eigen::Vector2d distort(const Eigen::Vector2d& xn) const;
  // Inverse of distort() by Newton's method on the model's Jacobian (fisheye: on
  // theta); exact to 1e-12 wherever the model is monotonic.
  Eigen::Vector2d undistort(const Eigen::Vector2d& xd) const;

  // Normalised (undistorted) coordinates to pixels and back.
  Eigen::Vector2d to_pixel(const Eigen::Vector2d& xn) const;
  Eigen::Vector2d to_normalised(const Eigen::Vector2d& pixel) const;
};

struct Pose {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  // world -> camera
  Eigen::Vector3d t = Eigen::Vector3d::Zero();      // metres

  Eigen::Vector3d centre() const { return -R.transpose() * t; }
  Eigen::Vector3d to_camera(const Eigen::Vector3d& X) const { return R * X + t; }
  // A pose whose camera sits at `centre` looking at `target`, with `up` as
  // the world direction that appears up in the image.
  static Pose look_at(const Eigen::Vector3d& centre, const Eigen::Vector3d& target,
                      const Eigen::Vector3d& up = Eigen::Vector3d::UnitZ());
  static Pose from_centre(const Eigen::Matrix3d& R, const Eigen::Vector3d& centre) {
    return Pose{R, -R * centre};
  }
};

struct Camera {
  Intrinsics intrinsics;
  Pose pose;

  // Projects a world point to pixels; empty when behind the camera.
  std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& X) const;
  // The world-space ray through a pixel: unit direction from the centre.
  Eigen::Vector3d ray(const Eigen::Vector2d& pixel) const;
};

}  // namespace strata
