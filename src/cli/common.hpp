#pragma once
// Small parsing helpers shared by the command files.
#include "project/project_lock.hpp"

#include <CLI/CLI.hpp>
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

// The path checks at the door (core/door.hpp) attached to every option of every
// command by its name, so that a new command gets them by naming its options as the
// others do: DIR (the project folder; to be made by init and synth), FILE and FRAME
// (input files), --out (a file; a folder when its help begins "output folder"; either
// when it says "or folder"), OUT (a folder),
// --outline, --check-outline, --intrinsics, --targets (input files), --colour
// (a folder), --surface and --footprint (NAME=FILE). A refused path ends the command
// in one line before it takes the project lock or reads anything.
void guard_paths(CLI::App& app);

}  // namespace strata::cli
