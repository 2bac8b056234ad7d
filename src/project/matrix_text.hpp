#pragma once
// A 4x4 matrix as the database stores it: 16 numbers, row-major, 17 significant
// digits, so that the text reads back to the same doubles (scans, depth frames).
#include <Eigen/Core>

#include <string>

namespace strata {

std::string matrix_text(const Eigen::Matrix4d& m);
// Throws IoError naming `what` when the text does not hold 16 numbers.
Eigen::Matrix4d parse_matrix_text(const std::string& text, const std::string& what);

}  // namespace strata
