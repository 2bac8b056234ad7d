#include "importers/photos/photo_importer.hpp"

#include "core/door.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/hash.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "importers/photos/exif.hpp"
#include "project/media.hpp"
#include "project/records.hpp"

#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>

#include <fstream>
#include <map>

namespace fs = std::filesystem;

namespace strata {
namespace {

constexpr const char* kStage = "importer.photos";

enum class Format { jpeg, png, tiff, unknown };

Format sniff(const std::string& head) {
  auto b = [&](std::size_t i) { return i < head.size() ? std::uint8_t(head[i]) : 0; };
  if (b(0) == 0xFF && b(1) == 0xD8 && b(2) == 0xFF) return Format::jpeg;
  if (head.rfind("\x89PNG\r\n\x1a\n", 0) == 0) return Format::png;
  if (head.rfind("II*", 0) == 0 || head.rfind("MM\0*", 0) == 0) return Format::tiff;
  return Format::unknown;
}

// A JPEG stream ends with the EOI marker (FF D9); cameras and editors may pad
// after it, so look at the last bytes. libjpeg silently fills a truncated file
// with grey, so this check is what catches a cut-off copy from a memory card.
bool jpeg_has_end_marker(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  const std::streamoff tail = std::min<std::streamoff>(size, 4096);
  std::string buf(std::size_t(tail), '\0');
  in.seekg(size - tail);
  in.read(buf.data(), tail);
  // Byte stuffing (FF 00) keeps FF D9 out of the entropy-coded data, so an EOI
  // near the end means the stream was written completely.
  for (std::size_t i = buf.size(); i-- > 1;) {
    if (std::uint8_t(buf[i - 1]) == 0xFF && std::uint8_t(buf[i]) == 0xD9) return true;
  }
  return false;
}

}  // namespace

std::string check_image_file(const fs::path& path) {
  std::error_code ec;
  try {
    door::input_file(path, "");
  } catch (const Error& e) {  // the reason alone: the caller names the file
    const std::string why = e.what(), quoted = "'" + path.string() + "' ";
    return why.rfind(quoted, 0) == 0 ? why.substr(quoted.size()) : why;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return "cannot be opened for reading";
  std::string head(16, '\0');
  in.read(head.data(), std::streamsize(head.size()));
  head.resize(std::size_t(in.gcount()));
  if (head.empty()) return "empty file";
  const Format format = sniff(head);
  if (format == Format::unknown) return "not a JPEG, PNG or TIFF image";
  if (format == Format::jpeg && !jpeg_has_end_marker(path)) return "truncated JPEG (no end marker)";
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
  // Decoding at 1/8 scale still reads the whole entropy-coded stream, which
  // catches corrupt data at a fraction of the cost of a full decode.
  const int flags = format == Format::jpeg ? cv::IMREAD_REDUCED_GRAYSCALE_8 : cv::IMREAD_GRAYSCALE;
  cv::Mat img;
  try {
    img = cv::imread(path.string(), flags);
  } catch (const cv::Exception&) {
    return "cannot be decoded";
  }
  if (img.empty()) return "cannot be decoded";
  return {};
}

PhotoImportSummary import_photos(Project& project, const PhotoImportOptions& options,
                                 const std::vector<fs::path>& files) {
  auto& db = project.db();
  const LayerRecord layer = require_layer(db, options.layer);
  PhotoImportSummary summary;

  struct Candidate {
    fs::path path;
    std::string sha;
    PhotoMetadata meta;
  };
  std::vector<Candidate> good;
  std::map<std::string, std::string> seen_in_batch;  // sha -> file
  {
    Progress progress("checking photos", files.size());
    for (const auto& f : files) {
      check_cancelled();
      progress.step();
      if (std::string why = check_image_file(f); !why.empty()) {
        summary.bad.push_back(fmt::format("{}: {}", f.string(), why));
        continue;
      }
      Candidate c{f, sha256_file(f), {}};
      try {
        c.meta = read_photo_metadata(f);
      } catch (const InputError& e) {
        summary.bad.push_back(e.what());
        continue;
      }
      if (c.meta.width <= 0 || c.meta.height <= 0) {
        summary.bad.push_back(fmt::format("{}: image size unknown", f.string()));
        continue;
      }
      if (auto it = seen_in_batch.find(c.sha); it != seen_in_batch.end()) {
        summary.already_present.push_back(
            fmt::format("{} (same content as {} in this batch)", f.string(), it->second));
        continue;
      }
      seen_in_batch[c.sha] = f.string();
      good.push_back(std::move(c));
    }
    progress.finish();
  }
  if (!summary.bad.empty() && !options.skip_bad) {
    std::string list;
    for (const auto& b : summary.bad) list += "\n  " + b;
    throw InputError(fmt::format(
        "{}: {} of {} files cannot be imported; nothing was imported (use --skip-bad to import "
        "the others):{}",
        kStage, summary.bad.size(), files.size(), list));
  }

  fault::point("import.photos.checked");
  Transaction tx(db);
  MediaBatch media(project.media_dir());
  for (const auto& c : good) {
    check_cancelled();
    if (auto existing = find_image_by_sha(db, c.sha)) {
      if (existing->layer_id == layer.id) {
        summary.already_present.push_back(fmt::format("{} (already imported as {})", c.path.string(), existing->name));
        continue;
      }
      // A photo records one state of the surface: in two layers it would be two
      // states at once. Refused like a bad file, not skipped as a repeat.
      std::string other = "another layer";
      for (const auto& l : list_layers(db))
        if (l.id == existing->layer_id) other = "layer " + l.name;
      const std::string why = fmt::format("{}: {}: the same photo is already in {} (as {}); a photo belongs to one "
                                          "layer",
                                          kStage, c.path.string(), other, existing->name);
      if (!options.skip_bad) throw InputError(why + "; nothing was imported");
      summary.bad.push_back(why);
      continue;
    }
    const std::string name = c.path.filename().string();
    for (const auto& other : find_images_by_name(db, name)) {
      if (other.layer_id == layer.id) {
        throw InputError(fmt::format(
            "{}: {}: a different photo named '{}' is already in layer {}; rename one of them",
            kStage, c.path.string(), name, layer.name));
      }
    }
    CameraRecord cam;
    cam.make = c.meta.make;
    cam.model = c.meta.model;
    cam.width = c.meta.width;
    cam.height = c.meta.height;
    cam.focal_mm = c.meta.focal_mm;
    cam.focal_35mm = c.meta.focal_35mm;
    const FocalPrior prior = focal_prior(c.meta);
    cam.focal_px = prior.focal_px;
    cam.sensor_width_mm = prior.sensor_width_mm;
    cam.focal_source = prior.source;
    if (!prior.focal_px) summary.without_exif.push_back(c.path.string());

    ImageRecord im;
    im.layer_id = layer.id;
    im.name = name;
    im.sha256 = c.sha;
    im.media_path = media.store(c.path, c.sha);
    fault::point("import.photos.media_stored");
    im.bytes = std::int64_t(fs::file_size(c.path));
    im.width = c.meta.width;
    im.height = c.meta.height;
    im.camera_id = find_or_insert_camera(db, cam);
    im.captured_at = c.meta.captured_at;
    im.exif_ok = prior.focal_px.has_value();
    insert_image(db, im);
    fault::point("import.photos.row_inserted");
    ++summary.imported;
  }
  fault::point("import.photos.before_commit");
  tx.commit();
  fault::point("import.photos.after_commit");
  media.commit();
  return summary;
}

}  // namespace strata
