#include "geometry/camera.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <cmath>

namespace strata {

const char* to_string(CameraModel model) {
  switch (model) {
    case CameraModel::radial:
      return "radial";
    case CameraModel::brown:
      return "brown";
    case CameraModel::fisheye:
      return "fisheye";
  }
  return "?";
}

std::optional<CameraModel> camera_model_from_string(const std::string& name) {
  if (name == "radial") return CameraModel::radial;
  if (name == "brown") return CameraModel::brown;
  if (name == "fisheye") return CameraModel::fisheye;
  return std::nullopt;
}

namespace {

// Fisheye: theta_d(theta) and its derivative.
double fisheye_theta_d(const Intrinsics& k, double theta) {
  const double t2 = theta * theta;
  return theta * (1.0 + t2 * (k.k1 + t2 * (k.k2 + t2 * (k.k3 + t2 * k.k4))));
}
double fisheye_dtheta_d(const Intrinsics& k, double theta) {
  const double t2 = theta * theta;
  return 1.0 + t2 * (3 * k.k1 + t2 * (5 * k.k2 + t2 * (7 * k.k3 + t2 * 9 * k.k4)));
}

// Brown: distorted point and its 2 x 2 Jacobian with respect to the undistorted one.
Eigen::Vector2d brown_distort(const Intrinsics& k, const Eigen::Vector2d& x, Eigen::Matrix2d* J) {
  const double u = x.x(), v = x.y();
  const double r2 = u * u + v * v;
  const double radial = 1.0 + r2 * (k.k1 + r2 * (k.k2 + r2 * k.k3));
  const Eigen::Vector2d d(u * radial + 2 * k.p1 * u * v + k.p2 * (r2 + 2 * u * u),
                          v * radial + k.p1 * (r2 + 2 * v * v) + 2 * k.p2 * u * v);
  if (J) {
    const double dradial = k.k1 + r2 * (2 * k.k2 + 3 * k.k3 * r2);  // d radial / d r2
    (*J)(0, 0) = radial + 2 * u * u * dradial + 2 * k.p1 * v + 6 * k.p2 * u;
    (*J)(0, 1) = 2 * u * v * dradial + 2 * k.p1 * u + 2 * k.p2 * v;
    (*J)(1, 0) = 2 * u * v * dradial + 2 * k.p1 * u + 2 * k.p2 * v;
    (*J)(1, 1) = radial + 2 * v * v * dradial + 6 * k.p1 * v + 2 * k.p2 * u;
  }
  return d;
}

}  // namespace

Eigen::Vector2d Intrinsics::distort(const Eigen::Vector2d& xn) const {
  switch (model) {
    case CameraModel::radial: {
      const double r2 = xn.squaredNorm();
      return xn * (1.0 + k1 * r2 + k2 * r2 * r2);
    }
    case CameraModel::brown:
      return brown_distort(*this, xn, nullptr);
    case CameraModel::fisheye: {
      const double r = xn.norm();
      if (r < 1e-12) return xn;
      return xn * (fisheye_theta_d(*this, std::atan(r)) / r);
    }
  }
  return xn;
}

Eigen::Vector2d Intrinsics::undistort(const Eigen::Vector2d& xd) const {
  switch (model) {
    case CameraModel::radial:
    case CameraModel::brown: {
      // Newton on distort(x) = xd from x = xd; radial is brown with k3 = p1 = p2 = 0.
      Intrinsics b = *this;
      if (model == CameraModel::radial) b.k3 = b.p1 = b.p2 = 0;
      Eigen::Vector2d x = xd;
      for (int i = 0; i < 30; ++i) {
        Eigen::Matrix2d J;
        const Eigen::Vector2d e = brown_distort(b, x, &J) - xd;
        if (e.squaredNorm() < 1e-26) break;
        const double det = J.determinant();
        if (!(std::abs(det) > 1e-12)) break;  // the model folds over here
        x -= J.inverse() * e;
      }
      return x;
    }
    case CameraModel::fisheye: {
      const double rd = xd.norm();
      if (rd < 1e-12) return xd;
      double theta = rd;  // theta_d ~ theta for small distortion
      for (int i = 0; i < 30; ++i) {
        const double e = fisheye_theta_d(*this, theta) - rd;
        if (std::abs(e) < 1e-14) break;
        const double d = fisheye_dtheta_d(*this, theta);
        if (!(d > 1e-9)) break;
        theta -= e / d;
      }
      // Beyond 90 degrees there is no point on the normalised plane: clamp just short.
      theta = std::min(theta, 1.5707);
      return xd * (std::tan(theta) / rd);
    }
  }
  return xd;
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
