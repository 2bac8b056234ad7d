#pragma once
// Shared helpers for tests: scratch folders, paths to the source tree and the
// strata executable, running the CLI.
#include <filesystem>
#include <string>
#include <vector>

namespace strata::test {

// A fresh, empty folder under the build tree, unique to this process, removed when
// the object dies (kept when STRATA_KEEP_SCRATCH is set).
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& name);
  ~ScratchDir();
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& rel) const { return path_ / rel; }

 private:
  std::filesystem::path path_;
};

std::filesystem::path source_dir();      // the repository root
std::filesystem::path shared_data_dir(); // ../shared/data beside the repository (may not exist)
std::filesystem::path strata_exe();      // the built `strata` executable
std::filesystem::path binary_dir();      // the build tree (scratch space lives under it)

struct CommandResult {
  int exit_code = -1;
  std::string out;  // stdout
  std::string err;  // stderr
};
// Runs the strata executable with the given arguments (no shell quoting issues:
// each argument is passed as is).
CommandResult run_strata(const std::vector<std::string>& args);

// Writes text to a file, creating parent folders.
void write_text(const std::filesystem::path& path, const std::string& text);
std::string read_text(const std::filesystem::path& path);

// The lines of an OpenDroneMap gcp_list (e.g. the generator's) whose photo name starts
// with `photo_prefix` (e.g. "L1_"), after its CRS line, written to `out`: the importer
// refuses observations in photos that are not in the project.
void write_gcp_lines_of(const std::filesystem::path& gcp_list, const std::string& photo_prefix,
                        const std::filesystem::path& out);

// A listing of every file under a folder with its size and SHA-256, for
// "nothing changed" comparisons.
std::string tree_fingerprint(const std::filesystem::path& dir);

}  // namespace strata::test
