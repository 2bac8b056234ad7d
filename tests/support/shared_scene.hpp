#pragma once
// Scenes (a synthetic excavation, a processed project) built once and shared by every
// test process that asks for the same one.
//
// Why on disk and not in SetUpTestSuite alone: gtest_discover_tests registers every
// TEST as its own ctest test, and ctest runs each in its own process
// (`suite_test --gtest_filter=Suite.Name`), so a suite-level fixture runs once per
// test, not once per suite. The scene is therefore cached in the build tree, keyed by
// what made it (the parameters, and the size and time of the test executable and of
// `strata`, so a rebuilt generator or pipeline makes a new one), built under a lock
// file and published by an atomic rename, so parallel `ctest -j` processes neither
// race nor see half a scene. See docs/testing.md.
#include <filesystem>
#include <functional>
#include <string>

namespace strata::test {

// The folder of the scene `name` made with `parameters` (any text that tells its
// options apart): built by `build(folder)` when no process built it yet, else reused.
// The folder is shared: read it, never change it (copy_scene() what a test changes).
// A scene whose build threw is not kept; the exception reaches the caller.
std::filesystem::path shared_scene(const std::string& name, const std::string& parameters,
                                   const std::function<void(const std::filesystem::path&)>& build);

// Copies a shared scene (or a part of it) to `to`, for a test that changes it.
void copy_scene(const std::filesystem::path& from, const std::filesystem::path& to);

}  // namespace strata::test
