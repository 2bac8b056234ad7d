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

struct ImageRecord;

struct MediaCheckSummary {
  std::size_t photos = 0;
  std::size_t hashed = 0;  // read in full (not vouched for by the record of an earlier check)
};

// Checks that every photo's file in media/ still holds the bytes that were imported
// (its SHA-256), so that no stage silently uses an altered or missing photo. A full
// hash is costly (a layer is 0.2-1 GB), so a photo whose size and modification time
// equal those recorded at its last successful check (cache/media_checked.tsv) is
// taken as checked; a photo whose size differs from the import's is altered without
// reading it. Throws IoError naming the photos at fault, and what to do.
MediaCheckSummary verify_media(const std::filesystem::path& project_dir, const std::vector<ImageRecord>& photos);

// Relative media path for a hash and original file name (extension kept, lower case).
std::string media_relative_path(const std::string& sha256, const std::filesystem::path& original);

}  // namespace strata
