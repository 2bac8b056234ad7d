#pragma once
// importer.photos: copies photos of one layer into the media store, reads their
// EXIF and records images and cameras. All or nothing: a batch with a bad file
// imports nothing unless skip_bad is set.
#include "project/project.hpp"

#include <filesystem>
#include <string>
#include <vector>

namespace strata {

struct PhotoImportOptions {
  std::string layer;      // required: the layer the photos belong to
  bool skip_bad = false;  // import the good files and list the bad ones
};

struct PhotoImportSummary {
  int imported = 0;
  std::vector<std::string> already_present;  // same content already in the project
  std::vector<std::string> bad;              // "file: reason"
  std::vector<std::string> without_exif;     // accepted without a focal-length prior
};

PhotoImportSummary import_photos(Project& project, const PhotoImportOptions& options,
                                 const std::vector<std::filesystem::path>& files);

// Full validation of one image file: readable, a supported format, decodes
// completely. Returns an empty string when good, else the reason.
std::string check_image_file(const std::filesystem::path& path);

}  // namespace strata
