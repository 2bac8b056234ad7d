#include "geometry/camera.hpp"

#include "core/error.hpp"

namespace strata {

Eigen::Vector2d Intrinsics::distort(const Eigen::Vector2d& xn) const {
  const double r2 = xn.squaredNorm();
  return xn * (1.0 + k1 * r2 + k2 * r2 * r2);
}

Eigen::Vector2d Intrinsics::undistort(const Eigen::Vector2d& xd) const {
  Eigen::Vector2d x = xd;
  for (int i = 0; i < 50; ++i) {
    const double r2 = x.squaredNorm();
    const Eigen::Vector2d next = xd / (1.0 + k1 * r2 + k2 * r2 * r2);
    if ((next - x).squaredNorm() < 1e-24) return next;
    x = next;
  }
  return x;
}

Eigen::Vector2d Intrinsics::to_pixel(const Eigen::Vector2d& xn) const {
  const Eigen::Vector2d d = distort(xn);
  return {fx * d.x() + cx, fy * d.y() + cy};
}

Eigen::Vector2d Intrinsics::to_normalised(const Eigen::Vector2d& p) const {
  return undistort(Eigen::Vector2d((p.x() - cx) / fx, (p.y() - cy) / fy));
}

Pose Pose::look_at(const Eigen::Vector3d& centre, const Eigen::Vector3d& target,
                   const Eigen::Vector3d& up) {
  const Eigen::Vector3d z = (target - centre).normalized();
  Eigen::Vector3d x = z.cross(up);
  if (x.norm() < 1e-9) x = z.cross(Eigen::Vector3d::UnitY());  // looking straight along up
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);  // image down
  Eigen::Matrix3d R;
  R.row(0) = x.transpose();
  R.row(1) = y.transpose();
  R.row(2) = z.transpose();
  return from_centre(R, centre);
}

std::optional<Eigen::Vector2d> Camera::project(const Eigen::Vector3d& X) const {
  const Eigen::Vector3d Xc = pose.to_camera(X);
  if (Xc.z() <= 1e-9) return std::nullopt;
  return intrinsics.to_pixel(Xc.head<2>() / Xc.z());
}

Eigen::Vector3d Camera::ray(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d xn = intrinsics.to_normalised(pixel);
  return (pose.R.transpose() * Eigen::Vector3d(xn.x(), xn.y(), 1.0)).normalized();
}

}  // namespace strata
