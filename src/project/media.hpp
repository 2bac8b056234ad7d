#pragma once
// The media store: original photos under media/ab/<sha256>.<ext>, never modified,
// never duplicated. Files are written to a temporary name and renamed into place;
// a MediaBatch removes what it added unless committed, so a failed import leaves
// media/ as it was.
#include <filesystem>
#include <string>
#include <vector>

namespace strata {

class MediaBatch {
 public:
  explicit MediaBatch(std::filesystem::path media_dir) : media_dir_(std::move(media_dir)) {}
  ~MediaBatch();
  MediaBatch(const MediaBatch&) = delete;
  MediaBatch& operator=(const MediaBatch&) = delete;

  // Copies `source` into the store under its hash; returns the path relative to the
  // project folder ("media/ab/abcd....jpg"). A file already stored is not touched.
  std::string store(const std::filesystem::path& source, const std::string& sha256);
  // Keeps the files added so far.
  void commit() { added_.clear(); }

 private:
  std::filesystem::path media_dir_;
  std::vector<std::filesystem::path> added_;
};

// Relative media path for a hash and original file name (extension kept, lower case).
std::string media_relative_path(const std::string& sha256, const std::filesystem::path& original);

}  // namespace strata
