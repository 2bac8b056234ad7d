#include "project/media.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/hash.hpp"
#include "core/temporaries.hpp"
#include "project/records.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <fstream>
#include <map>
#include <optional>
#include <utility>

namespace fs = std::filesystem;

namespace strata {
namespace {

constexpr const char* kCheckedFile = "media_checked.tsv";  // under cache/
// A file modified this recently may change again within the file system's clock tick
// without its mtime moving (seconds): its state is not recorded, so it is hashed again
// next time (git's "racy clean" rule).
constexpr auto kRacyWindow = std::chrono::seconds(2);
constexpr std::size_t kProblemsListed = 5;  // photos named in the error; the rest are counted

// What a file looked like when its hash was last found right: size and mtime (ns).
using FileState = std::pair<std::uintmax_t, std::int64_t>;

std::map<std::string, FileState> read_checked(const fs::path& file) {
  std::map<std::string, FileState> checked;
  std::ifstream in(file);
  std::string rel;
  FileState state;
  while (in >> rel >> state.first >> state.second) checked[rel] = state;
  return checked;  // a damaged record only costs full hashes
}

// The record is a cache: failing to write it (read-only media) costs only time.
void write_checked(const fs::path& file, const std::map<std::string, FileState>& checked) {
  std::error_code ec;
  fs::create_directories(file.parent_path(), ec);
  std::string text;
  for (const auto& [rel, state] : checked) text += rel + '\t' + std::to_string(state.first) + '\t' + std::to_string(state.second) + '\n';
  try {
    write_bytes_atomically(file, "media", text);
  } catch (const Error&) {
    // Not written: the next run hashes the photos again.
  }
}

std::optional<FileState> state_of(const fs::path& path) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec) return std::nullopt;
  const auto mtime = fs::last_write_time(path, ec);
  if (ec) return std::nullopt;
  return FileState{size, std::int64_t(mtime.time_since_epoch().count())};
}

}  // namespace

MediaCheckSummary verify_media(const fs::path& project_dir, const std::vector<ImageRecord>& photos) {
  const fs::path record = project_dir / "cache" / kCheckedFile;
  std::map<std::string, FileState> checked = read_checked(record);
  MediaCheckSummary summary;
  std::vector<std::string> problems;
  bool record_changed = false;
  for (const auto& photo : photos) {
    ++summary.photos;
    const fs::path path = project_dir / photo.media_path;
    const auto state = state_of(path);
    std::string problem;
    if (!state) {
      problem = fmt::format("{} ({}) is missing", photo.name, photo.media_path);
    } else if (photo.bytes > 0 && state->first != std::uintmax_t(photo.bytes)) {
      problem = fmt::format("{} ({}) was altered: {} bytes, {} at import", photo.name, photo.media_path,
                            state->first, photo.bytes);
    } else {
      const auto it = checked.find(photo.media_path);
      if (it != checked.end() && it->second == *state) continue;
      ++summary.hashed;
      const std::string hash = sha256_file(path);
      if (hash == photo.sha256) {
        const auto recent = fs::file_time_type::clock::now() - kRacyWindow;
        if (fs::file_time_type(fs::file_time_type::duration(state->second)) < recent) {
          checked[photo.media_path] = *state;
          record_changed = true;
        }
        continue;
      }
      problem = fmt::format("{} ({}) was altered: its SHA-256 is now {:.12}..., {:.12}... at import", photo.name,
                            photo.media_path, hash, photo.sha256);
    }
    checked.erase(photo.media_path);
    problems.push_back(problem);
  }
  if (record_changed) write_checked(record, checked);
  if (problems.empty()) return summary;
  std::string named;
  for (std::size_t i = 0; i < problems.size() && i < kProblemsListed; ++i) named += (i ? "; " : "") + problems[i];
  if (problems.size() > kProblemsListed) named += fmt::format("; and {} more", problems.size() - kProblemsListed);
  throw IoError(fmt::format("media: {} of {} photo(s) no longer hold what was imported: {}. strata will not use them: "
                            "put the original files back under these names (from the card or a backup)",
                            problems.size(), photos.size(), named));
}

std::string media_relative_path(const std::string& sha256, const fs::path& original) {
  std::string ext = original.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return "media/" + sha256.substr(0, 2) + "/" + sha256 + ext;
}

MediaBatch::~MediaBatch() {
  for (const auto& p : added_) {
    std::error_code ec;
    fs::remove(p, ec);
    fs::remove(p.parent_path(), ec);  // only succeeds when empty
  }
}

std::string MediaBatch::store(const fs::path& source, const std::string& sha256) {
  const std::string rel = media_relative_path(sha256, source);
  const fs::path target = media_dir_.parent_path() / rel;
  if (fs::exists(target)) return rel;
  fs::create_directories(target.parent_path());
  const fs::path tmp = target.string() + ".part";
  const Temporary held(tmp);
  std::error_code ec;
  fs::copy_file(source, tmp, fs::copy_options::overwrite_existing, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw IoError(fmt::format("{}: cannot copy into the media store: {}", source.string(), ec.message()));
  }
  fs::permissions(tmp, fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read, ec);
  fault::point("import.photos.media_part_written");
  fs::rename(tmp, target, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw IoError(fmt::format("{}: cannot store in media/: {}", source.string(), ec.message()));
  }
  added_.push_back(target);
  return rel;
}

}  // namespace strata
