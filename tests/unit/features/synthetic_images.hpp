#pragma once
// Procedural test images for the features tests: multi-scale noise texture
// (stands in for soil and stones), known homographies, blobs at known positions.
#include <opencv2/core.hpp>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <filesystem>
#include <vector>

namespace strata::test {

// Colour texture: sum of uniform noise octaves (cell sizes 96 ... 2 px),
// upsampled bicubically, normalised to [10, 245]. Deterministic in `seed`.
cv::Mat noise_texture(int width, int height, std::uint64_t seed);

// dst(x) = src(H^-1 x), pixel-centre convention (cv::warpPerspective).
cv::Mat warp(const cv::Mat& src, const Eigen::Matrix3d& H, int width, int height);

// Homography induced by the plane n.X = d (camera-1 frame) between two cameras
// with the same calibration K: x2 ~ K (R + t n^T / d) K^-1 x1, where
// X2 = R X1 + t (H&Z 13.1).
Eigen::Matrix3d plane_homography(const Eigen::Matrix3d& K, const Eigen::Matrix3d& R,
                                 const Eigen::Vector3d& t, const Eigen::Vector3d& n, double d);

Eigen::Vector2d apply(const Eigen::Matrix3d& H, const Eigen::Vector2d& x);

// Writes a lossless PNG; throws on failure.
void write_png(const std::filesystem::path& path, const cv::Mat& image);

}  // namespace strata::test
