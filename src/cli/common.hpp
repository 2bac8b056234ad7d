#pragma once
// Small parsing helpers shared by the command files.
#include <Eigen/Core>

#include <string>
#include <vector>

namespace strata::cli {

// "E,N,Z" -> vector; InputError naming the option on bad input.
Eigen::Vector3d parse_vector3(const std::string& text, const std::string& option);
// "a,b,c,d" -> numbers; InputError naming the option when the count differs.
std::vector<double> parse_numbers(const std::string& text, std::size_t count, const std::string& option);

}  // namespace strata::cli
