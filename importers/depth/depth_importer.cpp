#include "importers/depth/depth_importer.hpp"

#include "core/door.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/hash.hpp"
#include "core/progress.hpp"
#include "project/media.hpp"
#include "project/records.hpp"

#include <fmt/format.h>

#include <cmath>
#include <map>

namespace fs = std::filesystem;

namespace strata {
namespace {

constexpr const char* kStage = "importer.depth";
constexpr double kMaxDepthScaleM = 0.1;  // metres per unit: 16 bits then reach 6.5 km, far beyond any sensor
constexpr double kMaxNoiseK = 0.1;       // 1/m: 10 cm at 1 m would be no depth camera

struct Candidate {
  fs::path depth;
  std::string sha;
  std::int64_t valid = 0;
  std::optional<fs::path> colour;
  std::string colour_sha;
  std::optional<Eigen::Matrix4d> pose;
};

// The recorded pose of every frame, by file name; frames without one refused.
std::map<std::string, Eigen::Isometry3d> poses_by_name(const fs::path& file, const std::vector<fs::path>& frames) {
  std::map<std::string, Eigen::Isometry3d> out;
  for (auto& [name, pose] : read_depth_poses(file)) out.emplace(name, pose);
  for (const auto& f : frames) {
    if (!out.count(f.filename().string())) {
      throw InputError(fmt::format("{}: {}: no pose for frame {}; nothing was imported", kStage, file.string(),
                                   f.filename().string()));
    }
  }
  return out;
}

void refuse_known(Database& db, const LayerRecord& layer, const std::string& sequence,
                  const std::vector<Candidate>& frames) {
  for (const auto& s : list_depth_sequences(db, layer.id)) {
    if (s.name == sequence) {
      throw InputError(fmt::format("{}: layer {} already has a depth sequence named '{}'; give another --sequence "
                                   "name; nothing was imported",
                                   kStage, layer.name, sequence));
    }
  }
  for (const auto& c : frames) {
    if (auto existing = find_depth_frame_by_sha(db, c.sha)) {
      throw InputError(fmt::format("{}: {}: the same depth frame is already imported (as {}); nothing was imported",
                                   kStage, c.depth.string(), existing->name));
    }
  }
}

}  // namespace

void DepthImportOptions::validate() const {
  if (layer.empty()) throw InputError(fmt::format("{}: --layer is required", kStage));
  if (!(depth_scale_m > 0 && depth_scale_m <= kMaxDepthScaleM)) {
    throw InputError(fmt::format("{}: --depth-scale {} must be metres per unit of the PNG, > 0 and <= {} (0.001 "
                                 "for millimetres)",
                                 kStage, depth_scale_m, kMaxDepthScaleM));
  }
  if (!(noise_k > 0 && noise_k <= kMaxNoiseK)) {
    throw InputError(fmt::format("{}: --noise-k {} must be > 0 and <= {} (1/m: sigma = k z^2)", kStage, noise_k,
                                 kMaxNoiseK));
  }
}

DepthImportSummary import_depth(Project& project, const DepthImportOptions& options, const std::vector<fs::path>& frames) {
  options.validate();
  if (frames.empty()) throw InputError(fmt::format("{}: no depth frames given", kStage));
  auto& db = project.db();
  const LayerRecord layer = require_layer(db, options.layer);
  if (options.poses && !project.site().origin_set) {
    throw InputError(fmt::format("{}: --poses {}: the site frame has no origin yet; import the markers first (or "
                                 "give 'strata init' an --origin)",
                                 kStage, options.poses->string()));
  }
  DepthImportSummary summary;
  summary.intrinsics = read_depth_intrinsics(options.intrinsics);
  summary.sequence = options.sequence ? *options.sequence : fs::absolute(frames.front()).parent_path().filename().string();
  if (summary.sequence.empty()) summary.sequence = "depth";
  std::map<std::string, Eigen::Isometry3d> poses;
  if (options.poses) poses = poses_by_name(*options.poses, frames);

  std::vector<Candidate> good;
  std::map<std::string, std::string> names, contents;  // file name / sha -> path, within the batch
  {
    Progress progress("reading depth frames", frames.size());
    for (const auto& f : frames) {
      progress.step();
      check_cancelled();
      std::error_code ec;
      door::input_file(f, fmt::format("{}: depth frame", kStage));
      const std::string name = f.filename().string();
      if (auto it = names.find(name); it != names.end()) {
        throw InputError(fmt::format("{}: {}: a second frame named '{}' (the first: {}); nothing was imported",
                                     kStage, f.string(), name, it->second));
      }
      names.emplace(name, f.string());
      Candidate c;
      c.depth = f;
      c.sha = sha256_file(f);
      if (auto it = contents.find(c.sha); it != contents.end()) {
        throw InputError(fmt::format("{}: {}: the same content as {} (a frame given twice?); nothing was imported",
                                     kStage, f.string(), it->second));
      }
      contents.emplace(c.sha, f.string());
      c.valid = read_depth_png(f, summary.intrinsics).valid;
      if (options.colour_dir) {
        const fs::path colour = *options.colour_dir / name;
        if (!fs::is_regular_file(colour, ec)) {
          throw InputError(fmt::format("{}: {}: no colour frame for {} (the same file name is looked for in "
                                       "--colour); nothing was imported",
                                       kStage, colour.string(), name));
        }
        check_colour_png(colour, summary.intrinsics);
        c.colour = colour;
        c.colour_sha = sha256_file(colour);
      }
      if (options.poses) c.pose = poses.at(name).matrix();
      good.push_back(std::move(c));
    }
    progress.finish();
  }
  refuse_known(db, layer, summary.sequence, good);
  fault::point("import.depth.checked");

  Transaction tx(db);
  MediaBatch media(project.media_dir());
  DepthSequenceRecord seq;
  seq.layer_id = layer.id;
  seq.name = summary.sequence;
  seq.intrinsics = summary.intrinsics;
  seq.depth_scale_m = options.depth_scale_m;
  seq.noise_k = options.noise_k;
  seq.intrinsics_file = options.intrinsics.filename().string();
  if (options.poses) seq.poses_file = options.poses->filename().string();
  const std::int64_t sequence_id = insert_depth_sequence(db, seq);
  fault::point("import.depth.sequence_inserted");
  for (std::size_t i = 0; i < good.size(); ++i) {
    check_cancelled();
    const Candidate& c = good[i];
    DepthFrameRecord r;
    r.sequence_id = sequence_id;
    r.frame = int(i);
    r.name = c.depth.filename().string();
    r.sha256 = c.sha;
    r.media_path = media.store(c.depth, c.sha);
    r.bytes = std::int64_t(fs::file_size(c.depth));
    r.valid_pixels = c.valid;
    if (c.colour) {
      r.colour_name = c.colour->filename().string();
      r.colour_sha256 = c.colour_sha;
      r.colour_media_path = media.store(*c.colour, c.colour_sha);
      ++summary.with_colour;
    }
    r.recorded_pose = c.pose;
    if (c.pose) ++summary.with_pose;
    insert_depth_frame(db, r);
    fault::point("import.depth.frame_inserted");
    summary.valid_pixels += c.valid;
    ++summary.frames;
  }
  fault::point("import.depth.before_commit");
  tx.commit();
  fault::point("import.depth.after_commit");
  media.commit();
  return summary;
}

}  // namespace strata
