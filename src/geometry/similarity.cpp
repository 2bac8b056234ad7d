#include "geometry/similarity.hpp"

#include "core/error.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>

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

}  // namespace strata
