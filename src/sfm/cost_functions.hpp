#pragma once
// Residual functors of the bundle adjustment, templated on the scalar so Ceres can
// differentiate them automatically (ceres::AutoDiffCostFunction wraps them in the .cpp).
// Internal to sfm/ and its tests: no Ceres header is needed here, only the maths.
//
// Parameter blocks (all double):
//   pose[6]        {w, t}: angle-axis w of the world->camera rotation R (radians,
//                  |w| = angle) and t of X_cam = R X_world + t (metres). One block,
//                  so Ceres' Schur eliminator runs its specialisation <2, 3, 6>.
//   intrinsics[10] {f, cx, cy, k1, k2, aspect, k3, k4, p1, p2}: fx = f, fy = f * aspect
//                  (pixels) and the lens coefficients of geometry/camera.hpp. One layout
//                  for every CameraModel: the entries a model does not use are held
//                  constant (bundle_adjustment.cpp), so they stay at zero.
//   point[3]       X_world (metres)
#include "geometry/camera.hpp"

#include <Eigen/Core>

#include <cmath>

namespace strata::sfm_detail {

// The first six keep the order of the radial-only block of earlier versions.
enum IntrinsicIndex {
  kFocal = 0, kCx = 1, kCy = 2, kK1 = 3, kK2 = 4, kAspect = 5, kK3 = 6, kK4 = 7, kP1 = 8, kP2 = 9
};
constexpr int kIntrinsicsSize = 10;
constexpr int kPoseSize = 6;

// Rotates p by the angle-axis vector w (Rodrigues' formula):
//   R p = p cos(th) + (k x p) sin(th) + k (k . p)(1 - cos(th)),  k = w / th.
// Near th = 0 the first-order form R p = p + w x p keeps value and derivative exact
// (the same trick as ceres::AngleAxisRotatePoint; sqrt is not differentiable at 0).
template <typename T>
void angle_axis_rotate(const T* w, const T* p, T* out) {
  const T theta2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
  if (theta2 > T(1e-30)) {
    using std::cos;
    using std::sin;
    using std::sqrt;
    const T theta = sqrt(theta2);
    const T c = cos(theta), s = sin(theta);
    const T k[3] = {w[0] / theta, w[1] / theta, w[2] / theta};
    const T kxp[3] = {k[1] * p[2] - k[2] * p[1], k[2] * p[0] - k[0] * p[2],
                      k[0] * p[1] - k[1] * p[0]};
    const T kdp = k[0] * p[0] + k[1] * p[1] + k[2] * p[2];
    for (int i = 0; i < 3; ++i) out[i] = p[i] * c + kxp[i] * s + k[i] * kdp * (T(1) - c);
  } else {
    const T wxp[3] = {w[1] * p[2] - w[2] * p[1], w[2] * p[0] - w[0] * p[2],
                      w[0] * p[1] - w[1] * p[0]};
    for (int i = 0; i < 3; ++i) out[i] = p[i] + wxp[i];
  }
}

// The lens model of Intrinsics::distort() on normalised coordinates (xn, yn), written
// once for doubles and Jets so the adjustment and geometry/camera.cpp agree (the unit
// tests compare the two). Formulas in geometry/camera.hpp.
template <typename T>
void distort_normalised(CameraModel model, const T* k, const T& xn, const T& yn, T* xd, T* yd) {
  const T r2 = xn * xn + yn * yn;
  switch (model) {
    case CameraModel::radial: {
      const T radial = T(1) + k[kK1] * r2 + k[kK2] * r2 * r2;
      *xd = xn * radial;
      *yd = yn * radial;
      return;
    }
    case CameraModel::brown: {
      // Brown (1971) / OpenCV: radial to r^6 plus decentring (tangential) terms.
      const T radial = T(1) + r2 * (k[kK1] + r2 * (k[kK2] + r2 * k[kK3]));
      const T xy = xn * yn;
      *xd = xn * radial + T(2) * k[kP1] * xy + k[kP2] * (r2 + T(2) * xn * xn);
      *yd = yn * radial + k[kP1] * (r2 + T(2) * yn * yn) + T(2) * k[kP2] * xy;
      return;
    }
    case CameraModel::fisheye: {
      // Equidistant Kannala-Brandt (2006): theta_d / r scales the normalised point.
      // At r = 0 the scale tends to 1 (theta ~ r); sqrt would have no derivative there.
      using std::atan;
      using std::sqrt;
      T scale(1);
      if (r2 > T(1e-20)) {
        const T r = sqrt(r2);
        const T theta = atan(r);
        const T t2 = theta * theta;
        const T theta_d = theta * (T(1) + t2 * (k[kK1] + t2 * (k[kK2] + t2 * (k[kK3] + t2 * k[kK4]))));
        scale = theta_d / r;
      }
      *xd = xn * scale;
      *yd = yn * scale;
      return;
    }
  }
  *xd = xn;
  *yd = yn;
}

// Reprojection residual of one observation, in units of its standard deviation:
//   r = (pi(K, lens, R X + t) - observed) / sigma_px.
// pi: x_n = X_c.xy / X_c.z, x_d = distort_normalised(x_n), u = fx x_d + cx, v = fy y_d + cy.
struct ReprojectionCost {
  ReprojectionCost(const Eigen::Vector2d& observed_px, double sigma_px,
                   CameraModel lens = CameraModel::radial)
      : u(observed_px.x()), v(observed_px.y()), inv_sigma(1.0 / sigma_px), model(lens) {}

  template <typename T>
  bool operator()(const T* pose, const T* intrinsics, const T* point, T* residual) const {
    T xc[3];
    angle_axis_rotate(pose, point, xc);
    xc[0] += pose[3];
    xc[1] += pose[4];
    xc[2] += pose[5];
    // A point behind the camera has no projection: reject the step rather than
    // let the division flip signs.
    if (!(xc[2] > T(1e-12))) return false;
    const T xn = xc[0] / xc[2], yn = xc[1] / xc[2];
    T xd, yd;
    distort_normalised(model, intrinsics, xn, yn, &xd, &yd);
    const T fx = intrinsics[kFocal];
    const T fy = intrinsics[kFocal] * intrinsics[kAspect];
    residual[0] = (fx * xd + intrinsics[kCx] - T(u)) * T(inv_sigma);
    residual[1] = (fy * yd + intrinsics[kCy] - T(v)) * T(inv_sigma);
    return true;
  }

  double u, v, inv_sigma;
  CameraModel model;
};

// Prior on a surveyed control marker, per axis: r_i = (X_i - S_i) / sigma_i,
// sigma in metres (E, N, Z). Together with the marker's reprojection residuals this
// fits the photo geometry and the survey in one least-squares problem.
struct MarkerPriorCost {
  MarkerPriorCost(const Eigen::Vector3d& surveyed, const Eigen::Vector3d& sigma)
      : s(surveyed), inv_sigma(sigma.cwiseInverse()) {}

  template <typename T>
  bool operator()(const T* point, T* residual) const {
    for (int i = 0; i < 3; ++i) residual[i] = (point[i] - T(s[i])) * T(inv_sigma[i]);
    return true;
  }

  Eigen::Vector3d s, inv_sigma;
};

}  // namespace strata::sfm_detail
