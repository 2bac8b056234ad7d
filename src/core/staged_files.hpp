#pragma once
// Output files written under staged names (dtm.next.tif beside dtm.tif) until every
// one of a command's files is complete, then swapped in by rename: a command that
// fails part-way (a full disk) leaves the files it would have replaced untouched.
// Destroyed before swap_in (the command failed), it removes the staged files.
#include "core/temporaries.hpp"

#include <filesystem>
#include <functional>
#include <iosfwd>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace strata {

class StagedFiles {
 public:
  // `stage`: the stage named in a rename error ("products", "volume").
  explicit StagedFiles(std::string stage) : stage_(std::move(stage)) {}
  StagedFiles(const StagedFiles&) = delete;
  StagedFiles& operator=(const StagedFiles&) = delete;
  ~StagedFiles();
  // The staged name of `final_path`: its stem + ".next" + its extension.
  std::filesystem::path add(const std::filesystem::path& final_path);
  // Adds `final_path` and fills its staged file through `fill` (a binary stream),
  // creating the folder when missing; throws IoError "<stage>: <final_path>: ..." when
  // the folder cannot be made, the file opened or the writing completed.
  void write(const std::filesystem::path& final_path, const std::function<void(std::ostream&)>& fill);
  // Every staged file takes its final name (rename: atomic, the old file replaced),
  // in the order added; throws IoError naming the file that could not be renamed (a
  // folder of a final name is refused before any rename).
  // `renamed_point` (core/fault.hpp) is passed after each rename. A file that names
  // others (an .obj its .mtl) goes last, so that it never names one not yet in place.
  void swap_in(std::string_view renamed_point = {});

 private:
  std::string stage_;
  std::vector<std::pair<std::filesystem::path, std::filesystem::path>> files_;
  std::vector<std::unique_ptr<Temporary>> held_;  // the staged names, for a stop that cannot wait
};

}  // namespace strata
