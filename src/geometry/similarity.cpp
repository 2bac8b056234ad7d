#include "geometry/similarity.hpp"

#include "core/error.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>

namespace strata {

Similarity3 Similarity3::inverse() const {
  Similarity3 inv;
  inv.scale = 1.0 / scale;
  inv.R = R.transpose();
  inv.t = -inv.scale * (inv.R * t);
  return inv;
}

double planar_spread_ratio(const std::vector<Eigen::Vector3d>& points) {
  if (points.size() < 2) return 0.0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p;
  mean /= double(points.size());
  Eigen::MatrixXd centred(points.size(), 3);
  for (std::size_t i = 0; i < points.size(); ++i) centred.row(i) = (points[i] - mean).transpose();
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(centred);
  const auto s = svd.singularValues();
  return s(0) > 0 ? s(1) / s(0) : 0.0;
}

Similarity3 fit_similarity(const std::vector<Eigen::Vector3d>& src,
                           const std::vector<Eigen::Vector3d>& dst, double min_spread_ratio) {
  STRATA_CHECK(src.size() == dst.size());
  if (src.size() < 3) {
    throw InputError(fmt::format(
        "a similarity needs at least 3 control markers, {} given", src.size()));
  }
  const double spread = std::min(planar_spread_ratio(src), planar_spread_ratio(dst));
  if (spread < min_spread_ratio) {
    throw InputError(fmt::format(
        "the control markers are (nearly) collinear (spread ratio {:.4f} < {}): "
        "the rotation about their line is undetermined; add a marker off that line",
        spread, min_spread_ratio));
  }
  Eigen::Matrix3Xd a(3, src.size()), b(3, dst.size());
  for (std::size_t i = 0; i < src.size(); ++i) {
    a.col(i) = src[i];
    b.col(i) = dst[i];
  }
  const Eigen::Matrix4d T = Eigen::umeyama(a, b, true);
  Similarity3 s;
  const Eigen::Matrix3d sR = T.topLeftCorner<3, 3>();
  s.scale = std::cbrt(sR.determinant());
  s.R = sR / s.scale;
  s.t = T.topRightCorner<3, 1>();
  return s;
}

Similarity3 fit_similarity_weighted(const std::vector<Eigen::Vector3d>& src,
                                    const std::vector<Eigen::Vector3d>& dst,
                                    const std::vector<Eigen::Vector3d>& sigma,
                                    double min_spread_ratio) {
  STRATA_CHECK(src.size() == dst.size() && sigma.size() == src.size());
  for (const auto& sg : sigma) {
    if (!(sg.minCoeff() > 0) || !sg.allFinite()) {
      throw InputError(fmt::format("a weighted similarity needs every sigma > 0, got ({}, {}, {})",
                                   sg.x(), sg.y(), sg.z()));
    }
  }
  Similarity3 s = fit_similarity(src, dst, min_spread_ratio);
  // Gauss-Newton on the whitened residuals r_i = W_i (s R x_i + t - y_i), W = diag(1/sigma),
  // with the updates s <- s exp(d_s), R <- exp([w]x) R, t <- t + d_t:
  //   dr/d(d_s) = W s R x,  dr/dw = -W [s R x]x,  dr/dt = W.
  constexpr int kMaxIterations = 50;
  constexpr double kStepTolerance = 1e-12;  // relative, on every update
  for (int it = 0; it < kMaxIterations; ++it) {
    Eigen::Matrix<double, 7, 7> JtJ = Eigen::Matrix<double, 7, 7>::Zero();
    Eigen::Matrix<double, 7, 1> Jtr = Eigen::Matrix<double, 7, 1>::Zero();
    for (std::size_t i = 0; i < src.size(); ++i) {
      const Eigen::Vector3d w = sigma[i].cwiseInverse();
      const Eigen::Vector3d sRx = s.scale * (s.R * src[i]);
      const Eigen::Vector3d r = (sRx + s.t - dst[i]).cwiseProduct(w);
      Eigen::Matrix<double, 3, 7> J;
      J.col(0) = sRx;
      Eigen::Matrix3d cross;
      cross << 0, -sRx.z(), sRx.y(), sRx.z(), 0, -sRx.x(), -sRx.y(), sRx.x(), 0;
      J.block<3, 3>(0, 1) = -cross;
      J.block<3, 3>(0, 4) = Eigen::Matrix3d::Identity();
      J = w.asDiagonal() * J;
      JtJ += J.transpose() * J;
      Jtr += J.transpose() * r;
    }
    const Eigen::Matrix<double, 7, 1> d = JtJ.ldlt().solve(-Jtr);
    if (!d.allFinite()) break;  // (numerically) singular: keep the current estimate
    s.scale *= std::exp(d(0));
    const Eigen::Vector3d w = d.segment<3>(1);
    if (w.norm() > 0) s.R = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix() * s.R;
    s.t += d.segment<3>(4);
    if (d.cwiseAbs().maxCoeff() < kStepTolerance * std::max(1.0, s.t.norm())) break;
  }
  return s;
}

}  // namespace strata
