#pragma once
// Small parsing helpers shared by the command files.
#include "project/project_lock.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace strata::cli {

// "E,N,Z" -> vector; InputError naming the option on bad input.
Eigen::Vector3d parse_vector3(const std::string& text, const std::string& option);
// "a,b,c,d" -> numbers; InputError naming the option when the count differs.
std::vector<double> parse_numbers(const std::string& text, std::size_t count, const std::string& option);

// The command line and --wait, set once by main() before any command runs.
void set_invocation(int argc, char** argv);
void set_lock_wait(double seconds);
// The write lock of project `dir`, taken by every command that changes a project
// before it opens it; the holder is recorded as this command line (without DIR).
ProjectLock lock_project(const std::string& dir);

}  // namespace strata::cli
