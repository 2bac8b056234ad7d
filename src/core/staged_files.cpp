#include "core/staged_files.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/temporaries.hpp"

#include <fmt/format.h>

#include <fstream>

namespace strata {

namespace fs = std::filesystem;

StagedFiles::~StagedFiles() {
  std::error_code ec;
  for (const auto& [staged, final_path] : files_) fs::remove(staged, ec);
  held_.clear();
}

fs::path StagedFiles::add(const fs::path& final_path) {
  fs::path staged = final_path;
  staged.replace_filename(final_path.stem().string() + ".next" + final_path.extension().string());
  files_.emplace_back(staged, final_path);
  held_.push_back(std::make_unique<Temporary>(staged));
  return staged;
}

void StagedFiles::write(const fs::path& final_path, const std::function<void(std::ostream&)>& fill) {
  std::error_code ec;
  if (final_path.has_parent_path()) fs::create_directories(final_path.parent_path(), ec);
  if (ec) {
    throw IoError(fmt::format("{}: {}: cannot create the folder {}: {}", stage_, final_path.string(),
                              final_path.parent_path().string(), ec.message()));
  }
  const fs::path staged = add(final_path);
  std::ofstream f(staged, std::ios::binary);
  if (!f) throw IoError(fmt::format("{}: {}: cannot open {} for writing", stage_, final_path.string(), staged.string()));
  fill(f);
  f.close();
  if (!f) throw IoError(fmt::format("{}: {}: write failed (disk full?)", stage_, final_path.string()));
}

void StagedFiles::swap_in(std::string_view renamed_point) {
  // A rename that cannot succeed (a folder holds the final name) is refused before any
  // file is renamed: the files that name others go last, and must not be the only ones
  // missing.
  for (const auto& [staged, final_path] : files_) {
    std::error_code ec;
    if (fs::is_directory(final_path, ec))
      throw IoError(fmt::format("{}: {}: cannot rename {} over it: it is a folder", stage_, final_path.string(),
                                staged.filename().string()));
  }
  for (const auto& [staged, final_path] : files_) {
    std::error_code ec;
    fs::rename(staged, final_path, ec);
    if (ec)
      throw IoError(fmt::format("{}: {}: cannot rename {} over it: {}", stage_, final_path.string(),
                                staged.filename().string(), ec.message()));
    if (!renamed_point.empty()) fault::point(renamed_point);
  }
  files_.clear();
  held_.clear();
}

}  // namespace strata
