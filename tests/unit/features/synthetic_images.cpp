#include "unit/features/synthetic_images.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <stdexcept>

namespace strata::test {

cv::Mat noise_texture(int width, int height, std::uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat acc(height, width, CV_32FC3, cv::Scalar::all(0));
  double amplitude = 1.0;
  for (int cell = 96; cell >= 2; cell /= 2) {
    cv::Mat coarse(height / cell + 3, width / cell + 3, CV_32FC3);
    rng.fill(coarse, cv::RNG::UNIFORM, cv::Scalar::all(-1), cv::Scalar::all(1));
    cv::Mat fine;
    cv::resize(coarse, fine, cv::Size(coarse.cols * cell, coarse.rows * cell), 0, 0,
               cv::INTER_CUBIC);
    acc += amplitude * fine(cv::Rect(cell, cell, width, height));
    amplitude *= 0.75;  // keep fine detail strong: SIFT needs corners at all scales
  }
  cv::Mat out;
  cv::normalize(acc, acc, 10, 245, cv::NORM_MINMAX);
  acc.convertTo(out, CV_8UC3);
  return out;
}

cv::Mat warp(const cv::Mat& src, const Eigen::Matrix3d& H, int width, int height) {
  cv::Mat h(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) h.at<double>(r, c) = H(r, c);
  cv::Mat dst;
  cv::warpPerspective(src, dst, h, cv::Size(width, height), cv::INTER_CUBIC,
                      cv::BORDER_CONSTANT, cv::Scalar::all(128));
  return dst;
}

Eigen::Matrix3d plane_homography(const Eigen::Matrix3d& K, const Eigen::Matrix3d& R,
                                 const Eigen::Vector3d& t, const Eigen::Vector3d& n, double d) {
  Eigen::Matrix3d H = K * (R + t * n.transpose() / d) * K.inverse();
  return H / H(2, 2);
}

Eigen::Vector2d apply(const Eigen::Matrix3d& H, const Eigen::Vector2d& x) {
  return (H * x.homogeneous()).hnormalized();
}

void write_png(const std::filesystem::path& path, const cv::Mat& image) {
  std::filesystem::create_directories(path.parent_path());
  if (!cv::imwrite(path.string(), image)) throw std::runtime_error("cannot write " + path.string());
}

}  // namespace strata::test
