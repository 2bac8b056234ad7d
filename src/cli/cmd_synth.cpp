// strata synth: writes a synthetic excavation with known truth.
#include "cli/commands.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "synthetic/synthetic.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <memory>
#include <string>

namespace strata::cli {
namespace {

struct SynthArgs {
  std::string out;
  std::string size = "small";
  std::uint64_t seed = 1;
  int stages = -1, photos = -1, width = -1, height = -1, threads = 0;
  std::string marker_pattern = "aruco";
  std::string lens = "radial";
  bool no_exif = false;
  bool scans = false;
  double scan_step_mrad = 0, scan_sigma = -1;
  bool depth = false;
  int depth_frames = -1;
  double depth_offset = -1, depth_aim = -1;
};

// The camera of each synthetic lens (docs/cameras.md, "Synthetic lenses").
void set_lens(const std::string& lens, SyntheticExcavationOptions& o) {
  using Lens = SyntheticExcavationOptions::Photos::Lens;
  if (lens == "radial") {
    o.photos.lens = Lens::radial;
  } else if (lens == "brown") {
    // A wide zoom at 16 mm on APS-C (24 mm equivalent).
    o.photos.lens = Lens::brown;
    o.photos.focal_ratio = 16.0 / 23.5;
  } else if (lens == "fisheye") {
    // An action camera: 1/2.3" sensor (6.17 mm wide); the focal from the field of view.
    o.photos.lens = Lens::fisheye;
    o.photos.sensor_width_mm = 6.17;
  } else {
    throw InputError("synth: --lens must be radial, brown or fisheye (got " + lens + ")");
  }
}

void run_synth(const SynthArgs& a) {
  if (a.size != "small" && a.size != "full")
    throw InputError("synth: --size must be small or full (got " + a.size + ")");
  auto o = SyntheticExcavationOptions::preset(a.size == "full" ? SyntheticExcavationOptions::Size::full
                                                               : SyntheticExcavationOptions::Size::small);
  o.seed = a.seed;
  set_lens(a.lens, o);
  o.photos.exif = !a.no_exif;
  o.render.threads = a.threads;
  if (a.marker_pattern == "quadrant") {
    o.site.marker_pattern = SyntheticExcavationOptions::Site::MarkerPattern::quadrant;
  } else if (a.marker_pattern != "aruco") {
    throw InputError("synth: --marker-pattern must be aruco or quadrant (got " + a.marker_pattern + ")");
  }
  o.scans.enabled = a.scans;
  if (a.scan_step_mrad > 0) o.scans.step_mrad = a.scan_step_mrad;
  if (a.scan_sigma >= 0) o.scans.sigma_m = a.scan_sigma;
  o.depth.enabled = a.depth;
  if (a.depth_frames >= 0) o.depth.frames = a.depth_frames;
  if (a.depth_offset >= 0) o.depth.edge_offset_m = a.depth_offset;
  if (a.depth_aim >= 0) o.depth.aim_share = a.depth_aim;
  if (a.stages >= 0) o.site.stages = a.stages;
  if (a.photos >= 0) o.photos.per_layer = a.photos;
  // A different width keeps the preset's aspect unless --height is given, and
  // scales the texture so that texels stay about as fine as the pixels.
  const int preset_width = o.photos.width;
  if (a.width >= 0) {
    o.photos.height = a.height >= 0 ? a.height : int(std::lround(double(a.width) * o.photos.height / o.photos.width));
    o.photos.width = a.width;
    o.render.texel = std::clamp(o.render.texel * preset_width / std::max(a.width, 1), 0.001, 0.005);
  } else if (a.height >= 0) {
    o.photos.height = a.height;
  }
  o.validate();
  log::info("synth: {} stages, {} layers x {} photos at {} x {} px, seed {}", o.site.stages, o.site.stages + 1,
            o.photos.per_layer, o.photos.width, o.photos.height, o.seed);
  const auto s = generate_excavation(o, a.out);
  fmt::print("wrote {}: {} layers, {} photos, {} markers, {} marker observations in {:.1f} s\n", s.out_dir.string(),
             s.layers, s.photos, s.markers, s.marker_observations, s.seconds);
  for (const auto& u : s.units)
    fmt::print("  unit {}: {:.4f} m3 removed over {:.3f} m2, mean {:.3f} m, max {:.3f} m\n", u.unit, u.volume_m3,
               u.area_m2, u.mean_thickness_m, u.max_thickness_m);
  fmt::print("  finds.csv: {} finds planted in the removed units, {} of them recorded in the wrong unit "
             "(truth/finds.csv)\n",
             s.finds, s.planted_contradictions);
  if (o.scans.enabled)
    fmt::print("  scans.csv: {} simulated laser scans, {} points (step {} mrad, range sigma {} mm), poses in "
               "scans/L<k>/S<n>_pose.txt\n",
               s.scans, s.scan_points, o.scans.step_mrad, 1000 * o.scans.sigma_m);
  if (o.depth.enabled)
    fmt::print("  depth/L<k>/: {} simulated depth frames ({} x {}, noise {} z^2), true and recorded (drifting) "
               "poses in poses_true.txt, poses_recorded.txt\n",
               s.depth_frames, o.depth.width, o.depth.height, o.depth.noise_k);
}

}  // namespace

void register_synth_command(CLI::App& app) {
  auto args = std::make_shared<SynthArgs>();
  CLI::App* cmd = app.add_subcommand(
      "synth",
      "Write a synthetic excavation with known truth: photos of every layer, surveyed\n"
      "markers, and the true cameras, surfaces and volumes to measure strata against.\n\n"
      "A 4 m x 3 m trench in EPSG:32636 (E 734000, N 4174000, Z 1450) is dug in K stages\n"
      "(default 3 units, so 4 recorded layers L1..L4): a pit cut, a stone wall standing\n"
      "proud, steep sides. Each layer is photographed hand-held (oblique from the edges,\n"
      "near-vertical over the trench) with ArUco DICT_4X4_50 targets GCP1..GCP8 around it.\n\n"
      "OUT gets site.json, units.csv, relations.csv, layers.csv, markers.csv (surveyed),\n"
      "finds.csv (surveyed finds, a few recorded in the wrong unit on purpose),\n"
      "gcp_list.txt (OpenDroneMap), photos/L<k>/*.jpg and truth/ (cameras.csv,\n"
      "surface.tif per layer, markers.csv, units.csv, finds.csv; cameras_lens.csv with every lens term).\n"
      "See docs/synthetic.md.\n\n"
      "Examples:\n"
      "  strata synth /tmp/dig --size small            4 x 20 photos at 1000 x 667, a minute\n"
      "  strata synth examples/data/dig --size full    4 x 40 photos at 2400 x 1600, minutes\n"
      "  strata synth /tmp/dig2 --seed 7 --stages 2 --photos 20\n"
      "Then load it: strata init site --crs EPSG:32636; strata import markers site OUT/markers.csv ...");
  cmd->add_option("OUT", args->out, "output folder; must not exist or be empty")->required();
  cmd->add_option("--size", args->size, "small (tests, seconds) or full (example dataset, minutes)")
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "random seed: the same seed gives the same files byte for byte")
      ->capture_default_str();
  cmd->add_option("--stages", args->stages, "units removed (1..8); layers recorded = stages + 1 [3]");
  cmd->add_option("--photos", args->photos, "photos per layer (3..500) [small 12, full 40]");
  cmd->add_option("--width", args->width, "image width in pixels [small 1000, full 2400]");
  cmd->add_option("--height", args->height, "image height in pixels [width x 2/3]");
  cmd->add_option("--marker-pattern", args->marker_pattern,
                  "aruco (coded targets, detected automatically) or quadrant (non-coded chequered\n"
                  "quadrant targets: click them and run 'strata markers guide')")
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "worker threads, 0 = all cores")->capture_default_str();
  cmd->add_option("--lens", args->lens,
                  "radial (a normal lens, mild barrel), brown (a wide DSLR zoom: strong barrel and "
                  "decentring) or fisheye (an action camera, 150 degrees diagonally); EXIF to match")
      ->capture_default_str();
  cmd->add_flag("--no-exif", args->no_exif, "write the photos without any EXIF (no focal length, no camera)");
  cmd->add_flag("--scans", args->scans,
                "also simulate a terrestrial laser scan of every layer: 3 tripod stations at the trench\n"
                "edge, 1.5 m up, occluded by the trench sides and stones, Gaussian range noise; binary\n"
                "PLY (x y z intensity, scanner frame) and the true pose per station under scans/L<k>/,\n"
                "listed in scans.csv (docs/range.md)");
  cmd->add_option("--scan-step-mrad", args->scan_step_mrad,
                  "angular step of the simulated scans, milliradians [2: 4-8 mm at the floor]");
  cmd->add_flag("--depth", args->depth,
                "also simulate a hand-held depth camera (RGB-D) sequence of every layer: 16-bit PNG\n"
                "depth in millimetres and RGB PNG per frame, intrinsics, true and drifting recorded\n"
                "poses under depth/L<k>/ (docs/range.md)");
  cmd->add_option("--depth-frames", args->depth_frames, "depth frames per layer, one loop round the trench [60]");
  cmd->add_option("--depth-offset", args->depth_offset,
                  "metres: the depth camera's loop runs this far outside the trench edge [0.3]; at 1.0 most\n"
                  "frames also see a marker or two (0..1)");
  cmd->add_option("--depth-aim", args->depth_aim,
                  "the depth camera aims at the floor this share of the way from the trench centre towards\n"
                  "itself [0.3]");
  cmd->add_option("--scan-sigma", args->scan_sigma, "range noise of the simulated scans, metres, one sigma [0.003]");
  cmd->callback([args] { run_synth(*args); });
}

}  // namespace strata::cli
