#include "project/media.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"

#include <algorithm>
#include <cctype>

namespace fs = std::filesystem;

namespace strata {

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
