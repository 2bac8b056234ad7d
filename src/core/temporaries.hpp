#pragma once
// Temporary files and folders a command is writing (a file under its temporary or
// staged name, a photo being copied into media/, a fresh dense folder). Each writer
// holds a Temporary while the path may exist under that name; when a command is
// stopped by a signal it could not honour at a safe point (core/signals.hpp), the
// stopping thread removes every path still held before the process ends, so that a
// stop leaves no staging behind. The normal ways out (success, an exception) keep
// removing their own temporaries as before.
#include <filesystem>

namespace strata {

class Temporary {
 public:
  explicit Temporary(std::filesystem::path path);
  ~Temporary();
  Temporary(const Temporary&) = delete;
  Temporary& operator=(const Temporary&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// Removes every path held by a Temporary now (files, or folders with their
// contents); returns how many existed. For the stopping thread only: the command is
// about to end.
int remove_temporaries();

}  // namespace strata
