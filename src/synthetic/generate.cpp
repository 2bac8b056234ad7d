// generate_excavation(): orchestration of the synthetic dataset. The maths lives in
// scene.cpp (geometry, materials), render.cpp (ray casting) and photo_set.cpp
// (cameras, sessions); this file validates, sequences, and writes.
#include "synthetic/synthetic.hpp"

#include "core/parallel.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "core/resources.hpp"
#include "crs/crs.hpp"
#include "exporters/raster/geotiff.hpp"
#include "synthetic/depth_camera.hpp"
#include "synthetic/finds.hpp"
#include "synthetic/noise.hpp"
#include "synthetic/photo_set.hpp"
#include "synthetic/render.hpp"
#include "synthetic/scans.hpp"
#include "synthetic/scene.hpp"
#include "synthetic/writers.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <unistd.h>

namespace fs = std::filesystem;

namespace strata {
namespace {

constexpr double kAreaThreshold = 0.001;     // metres: removed thickness counted as area
constexpr double kOcclusionTol = 0.005;      // metres: a marker centre hidden by more is not observed
constexpr double kMaxMarkerIncidence = 80.0; // degrees from the marker normal still observed
constexpr double kLensBlurSigma = 0.55;      // pixels: optics + demosaicing softness
constexpr double kVignetting = 0.22;         // relative fall-off at the image corner
constexpr double kMidGrey = 0.18;            // linear mean the auto-exposure aims for
constexpr std::int64_t kMaxGridNodes = 80'000'000;  // per layer: ~320 MB of Float32
constexpr const char* kMake = "Strata Synthetic";
constexpr const char* kModel = "SynthCam APS-C";
constexpr const char* kFisheyeModel = "SynthCam Action";  // a 1/2.3" action camera

const char* camera_name(const SyntheticExcavationOptions& o) {
  return o.photos.lens == SyntheticExcavationOptions::Photos::Lens::fisheye ? kFisheyeModel : kModel;
}

template <typename T>
void require(bool ok, const char* field, T value, const char* range) {
  if (!ok) throw InputError(fmt::format("synth: option {} must be {} (got {})", field, range, value));
}

std::string exif_time(const std::string& iso) {  // "2024-06-10T09:00:01" -> "2024:06:10 09:00:01"
  std::string s = iso;
  s[4] = ':';
  s[7] = ':';
  s[10] = ' ';
  return s;
}

// Camera response: vignetting, lens blur, auto-exposure, sRGB encoding and sensor
// noise (read noise plus shot noise growing with the signal), then 8-bit.
std::vector<std::uint8_t> develop(const synthetic::LinearImage& img, const Intrinsics& k,
                                  double noise_sigma, std::uint64_t seed) {
  const int w = img.width, h = img.height;
  cv::Mat lin(h, w, CV_32FC3);
  std::memcpy(lin.data, img.rgb.data(), img.rgb.size() * sizeof(float));
  const double rmax2 = std::pow(0.5 * w, 2) + std::pow(0.5 * h, 2);
  for (int v = 0; v < h; ++v) {
    auto* row = lin.ptr<float>(v);
    for (int u = 0; u < w; ++u) {
      const double r2 = (std::pow(u - k.cx, 2) + std::pow(v - k.cy, 2)) / rmax2;
      const float f = float(1.0 - kVignetting * r2);
      for (int c = 0; c < 3; ++c) row[3 * u + c] *= f;
    }
  }
  cv::GaussianBlur(lin, lin, cv::Size(), kLensBlurSigma, kLensBlurSigma, cv::BORDER_REFLECT);
  const cv::Scalar mean = cv::mean(lin);
  const double luminance = 0.2126 * mean[0] + 0.7152 * mean[1] + 0.0722 * mean[2];
  synthetic::Rng rng(seed);
  const double exposure = std::clamp(kMidGrey / std::max(luminance, 1e-6), 0.3, 4.0) * std::exp(rng.uniform(-0.08, 0.08));
  std::vector<std::uint8_t> out(3 * std::size_t(w) * std::size_t(h));
  const auto seed32 = std::uint32_t(rng.next());
  for (int v = 0; v < h; ++v) {
    const auto* row = lin.ptr<float>(v);
    for (int u = 0; u < w; ++u)
      for (int c = 0; c < 3; ++c) {
        const double l = std::max(0.0, row[3 * u + c] * exposure);
        const double s = l <= 0.0031308 ? 12.92 * l : 1.055 * std::pow(std::min(l, 1.0), 1 / 2.4) - 0.055;
        // Approximately Gaussian: sum of four uniforms (Irwin-Hall), unit variance.
        const std::int64_t key = (std::int64_t(v) * w + u) * 3 + c;
        double g = -2.0;
        for (std::uint32_t q = 0; q < 4; ++q) g += synthetic::hash_unit(key, q, seed32);
        g *= std::sqrt(3.0);
        const double sigma = noise_sigma * std::sqrt(0.4 + 1.2 * s);
        out[3 * (std::size_t(v) * std::size_t(w) + std::size_t(u)) + std::size_t(c)] =
            std::uint8_t(std::clamp(std::lround(255.0 * s + sigma * g), 0L, 255L));
      }
  }
  return out;
}

struct UnitVolume {
  double volume = 0, area = 0, max = 0;
};

// Exact integral of the difference of two bilinear height fields on the same
// nodes: per cell, the mean of the four corner differences times the cell area.
UnitVolume removed_volume(const synthetic::HeightGrid& before, const synthetic::HeightGrid& after) {
  UnitVolume r;
  const double area = before.cell * before.cell;
  for (int j = 0; j + 1 < before.ny; ++j)
    for (int i = 0; i + 1 < before.nx; ++i) {
      double mean = 0;
      for (int q = 0; q < 4; ++q) {
        const double d = double(before.node(i + (q & 1), j + (q >> 1))) - after.node(i + (q & 1), j + (q >> 1));
        mean += 0.25 * d;
        r.max = std::max(r.max, d);
      }
      r.volume += mean * area;
      if (mean > kAreaThreshold) r.area += area;
    }
  return r;
}

// The markers a station measured as targets, in its scanner's frame, as
// 'strata register scan --targets' reads them.
void write_scan_targets(const fs::path& file, const std::vector<synthetic::TargetObservation>& targets,
                        const std::string& layer, std::size_t station, double sigma_m) {
  synthetic::TextFile t(file);
  t.out() << fmt::format("# markers measured as targets by the scanner of {} station {}: scanner frame, metres, "
                         "{:.1f} mm noise per axis\nname,x,y,z\n",
                         layer, station, 1000 * sigma_m);
  for (const auto& m : targets)
    t.out() << fmt::format("{},{:.4f},{:.4f},{:.4f}\n", m.name, m.scanner.x(), m.scanner.y(), m.scanner.z());
  t.close();
}

// The simulated laser scans of layer k: per station, scans/L<k>/S<n>.ply in the
// scanner's frame, its true pose S<n>_pose.txt (scanner -> site frame, the 4x4 that
// 'strata import scan --transform' reads), the markers it measured as targets
// S<n>_targets.csv, and a line of scans.csv.
void write_layer_scans(const synthetic::Scene& scene, int k, const fs::path& dir, std::vector<std::string>& lines,
                       SyntheticExcavationSummary& summary) {
  using namespace synthetic;
  const auto& o = scene.options();
  const std::string layer = fmt::format("L{}", k + 1);
  fs::create_directories(dir / "scans" / layer);
  const Eigen::Vector3d origin(o.site.origin_e, o.site.origin_n, o.site.origin_z);
  const auto stations = plan_scan_stations(scene, k, o.seed);
  for (std::size_t s = 0; s < stations.size(); ++s) {
    check_cancelled();
    const SimulatedScan scan = simulate_scan(scene, k, stations[s], mix64(o.seed * 7001 + std::uint64_t(k) * 31 + s));
    const std::string name = fmt::format("S{}", s + 1);
    const fs::path ply = fs::path("scans") / layer / (name + ".ply");
    const fs::path pose = fs::path("scans") / layer / (name + "_pose.txt");
    write_scan_ply(dir / ply, scan.points, scan.intensity,
                   fmt::format("strata synthetic laser scan, layer {}, station {}, seed {}", layer, s + 1, o.seed));
    TextFile t(dir / pose);
    t.out() << fmt::format("# true pose of {} station {}: scanner frame -> site frame (EPSG:{} minus origin "
                           "{:.3f} {:.3f} {:.3f}), row-major\n",
                           layer, s + 1, o.site.epsg, origin.x(), origin.y(), origin.z());
    const Eigen::Matrix4d m = stations[s].scanner_to_site();
    for (int r = 0; r < 4; ++r)
      t.out() << fmt::format("{:.12f} {:.12f} {:.12f} {:.12f}\n", m(r, 0), m(r, 1), m(r, 2), m(r, 3));
    t.close();
    write_scan_targets(dir / "scans" / layer / (name + "_targets.csv"),
                       observe_scan_targets(scene, k, stations[s], mix64(o.seed * 7013 + std::uint64_t(k) * 37 + s)),
                       layer, s + 1, o.scans.target_sigma_m);
    const Eigen::Vector3d c = stations[s].origin + origin;
    lines.push_back(fmt::format("{},{},{},{},{:.4f},{:.4f},{:.4f},{:.6f},{}", layer, ply.string(), pose.string(),
                                o.scans.sigma_m, c.x(), c.y(), c.z(), stations[s].yaw, scan.points.size()));
    summary.scans++;
    summary.scan_points += std::int64_t(scan.points.size());
  }
}

Eigen::Vector3d site_origin(const SyntheticExcavationOptions& o) {
  return {o.site.origin_e, o.site.origin_n, o.site.origin_z};
}

double focal_mm(const Intrinsics& intrinsics, double sensor_width_mm) {
  return intrinsics.fx / intrinsics.width * sensor_width_mm;
}

// Markers: truth and a 'surveyed' copy with Gaussian noise; returns the surveyed
// positions (CRS).
std::vector<Eigen::Vector3d> write_markers(const synthetic::Scene& scene, const SyntheticExcavationOptions& o,
                                           const fs::path& dir) {
  using namespace synthetic;
  const auto& site = o.site;
  const Eigen::Vector3d origin = site_origin(o);
  Rng survey(o.seed ^ 0x5EB7E7ull);
  std::vector<Eigen::Vector3d> surveyed;
  TextFile truth(dir / "truth" / "markers.csv"), meas(dir / "markers.csv");
  truth.out() << "name,E,N,Z,sigma,kind\n";
  meas.out() << "name,E,N,Z,sigma,kind\n";
  for (const auto& m : scene.markers()) {
    const Eigen::Vector3d t = m.centre + origin;
    const Eigen::Vector3d s = t + site.survey_sigma * Eigen::Vector3d(survey.normal(), survey.normal(), survey.normal());
    surveyed.push_back(s);
    const char* kind = m.check ? "check" : "control";
    truth.out() << fmt::format("{},{:.6f},{:.6f},{:.6f},0,{}\n", m.name, t.x(), t.y(), t.z(), kind);
    meas.out() << fmt::format("{},{:.4f},{:.4f},{:.4f},{},{}\n", m.name, s.x(), s.y(), s.z(), site.survey_sigma, kind);
  }
  truth.close();
  meas.close();
  return surveyed;
}

synthetic::ExifFields photo_exif(const SyntheticExcavationOptions& o, const Intrinsics& intrinsics,
                                 const std::string& layer, int k, const synthetic::PlannedPhoto& p) {
  using namespace synthetic;
  const double sensor = o.photos.sensor_width_mm;
  const double focal = focal_mm(intrinsics, sensor);
  ExifFields exif;
  exif.write = o.photos.exif;
  exif.make = kMake;
  exif.model = camera_name(o);
  exif.software = "strata synth 0.1.0";
  exif.description = fmt::format("strata synthetic excavation, seed {}, layer {}", o.seed, layer);
  exif.datetime = exif_time(session_time(k, p.seconds_after_start));
  exif.focal_mm = focal;
  exif.focal_35mm = int(std::lround(focal * 36.0 / sensor));
  exif.sensor_width_mm = sensor;
  exif.width = intrinsics.width;
  exif.height = intrinsics.height;
  return exif;
}

// The true observations of every marker centre photo p sees, as lines of gcp_list.txt
// (with the surveyed positions).
std::vector<std::string> marker_observations(const synthetic::Scene& scene, int k, const synthetic::PlannedPhoto& p,
                                             const Intrinsics& intrinsics,
                                             const std::vector<Eigen::Vector3d>& surveyed) {
  using namespace synthetic;
  std::vector<std::string> lines;
  const Eigen::Vector3d c = p.camera.pose.centre();
  for (std::size_t m = 0; m < scene.markers().size(); ++m) {
    const Eigen::Vector3d& x = scene.markers()[m].centre;
    const auto px = p.camera.project(x);
    if (!px || px->x() < 0 || px->y() < 0 || px->x() > intrinsics.width - 1 || px->y() > intrinsics.height - 1)
      continue;
    const Eigen::Vector3d d = (x - c).normalized();
    if (-d.z() < std::cos(kMaxMarkerIncidence * 3.141592653589793 / 180)) continue;
    const RayHit hit = cast_ray(scene, k, c, d);
    if (hit.where == RayHit::Where::sky || hit.t < (x - c).norm() - kOcclusionTol) continue;
    const Eigen::Vector3d& s = surveyed[m];
    lines.push_back(fmt::format("{:.4f}\t{:.4f}\t{:.4f}\t{:.4f}\t{:.4f}\t{}\t{}", s.x(), s.y(), s.z(), px->x(),
                                px->y(), p.name, scene.markers()[m].name));
  }
  return lines;
}

// Renders, develops and writes every planned photo of layer k (in parallel); returns
// the marker observations of each photo, in the plan's order.
std::vector<std::vector<std::string>> photograph_layer(const synthetic::Scene& scene, int k,
                                                       const synthetic::LayerTexture& texture,
                                                       const synthetic::Lighting& light,
                                                       const std::vector<synthetic::PlannedPhoto>& plan,
                                                       const Intrinsics& intrinsics,
                                                       const std::vector<Eigen::Vector3d>& surveyed,
                                                       const SyntheticExcavationOptions& o, const fs::path& dir) {
  using namespace synthetic;
  const std::string layer = fmt::format("L{}", k + 1);
  RenderSettings settings;
  settings.edge_samples = o.render.edge_samples;
  std::vector<std::vector<std::string>> observations(plan.size());
  Progress progress(fmt::format("synth: photographing {}", layer), plan.size());
  tbb::parallel_for(std::size_t(0), plan.size(), [&](std::size_t i) {
    check_cancelled();
    const PlannedPhoto& p = plan[i];
    const LinearImage img = render_view(scene, k, texture, light, p.camera, settings);
    const auto rgb = develop(img, intrinsics, o.photos.noise_sigma, mix64(o.seed * 1000003 + std::uint64_t(k) * 1009 + i));
    write_jpeg(dir / "photos" / layer / p.name, rgb, img.width, img.height, o.photos.jpeg_quality,
               photo_exif(o, intrinsics, layer, k, p));
    observations[i] = marker_observations(scene, k, p, intrinsics, surveyed);
    progress.step();
  });
  progress.finish();
  return observations;
}

// The end of a line of the true cameras: the rotation row by row, then the centre (CRS).
std::string pose_columns(const synthetic::PlannedPhoto& p, const Eigen::Vector3d& origin) {
  const auto& R = p.camera.pose.R;
  const Eigen::Vector3d c = p.camera.pose.centre() + origin;
  std::string text;
  for (int r = 0; r < 3; ++r)
    for (int q = 0; q < 3; ++q) text += fmt::format(",{:.17g}", R(r, q));
  return text + fmt::format(",{:.17g},{:.17g},{:.17g}\n", c.x(), c.y(), c.z());
}

// The true cameras of a layer, as `strata export cameras --format csv` writes them
// and, with every lens term, as `--format csv-lens`.
void write_true_cameras(const std::vector<synthetic::PlannedPhoto>& plan, const Eigen::Vector3d& origin,
                        const fs::path& truth_dir) {
  using namespace synthetic;
  TextFile cams(truth_dir / "cameras.csv");
  cams.out() << "image,fx,fy,ppx,ppy,k1,k2,r11,r12,r13,r21,r22,r23,r31,r32,r33,X,Y,Z\n";
  for (const auto& p : plan) {
    const auto& K = p.camera.intrinsics;
    cams.out() << fmt::format("{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}", p.name, K.fx, K.fy, K.cx, K.cy,
                              K.k1, K.k2);
    cams.out() << pose_columns(p, origin);
  }
  cams.close();
  TextFile lens(truth_dir / "cameras_lens.csv");
  lens.out() << "image,model,fx,fy,ppx,ppy,k1,k2,k3,k4,p1,p2,r11,r12,r13,r21,r22,r23,r31,r32,r33,X,Y,Z\n";
  for (const auto& p : plan) {
    const auto& K = p.camera.intrinsics;
    lens.out() << fmt::format("{},{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}",
                              p.name, to_string(K.model), K.fx, K.fy, K.cx, K.cy, K.k1, K.k2, K.k3, K.k4,
                              K.p1, K.p2);
    lens.out() << pose_columns(p, origin);
  }
  lens.close();
}

// Truth surface: cell centres on a grid aligned to multiples of the cell in the CRS.
// The grid is in CRS coordinates (the georeference's origin is zero), so each
// height is rounded to Float32 once, from the absolute height in double.
void write_truth_surface(const synthetic::Scene& scene, int k, const SyntheticExcavationOptions& o,
                         const fs::path& path) {
  const Eigen::Vector3d origin = site_origin(o);
  Dtm truth;
  RasterGrid& g = truth.grid;
  g.cell = o.render.truth_cell;
  const double margin = o.render.truth_margin;
  g.x_min = std::floor((origin.x() + scene.trench_x0() - margin) / g.cell) * g.cell;
  g.y_max = std::ceil((origin.y() + scene.trench_y1() + margin) / g.cell) * g.cell;
  g.width = int(std::ceil((origin.x() + scene.trench_x1() + margin - g.x_min) / g.cell));
  g.height = int(std::ceil((g.y_max - (origin.y() + scene.trench_y0() - margin)) / g.cell));
  truth.z.resize(g.cells());
  const synthetic::HeightGrid& surface = scene.surface(k);
  tbb::parallel_for(0, g.height, [&](int r) {
    for (int q = 0; q < g.width; ++q) {
      const double x = g.x_centre(q) - origin.x();
      const double y = g.y_centre(r) - origin.y();
      truth.z[g.index(q, r)] = surface.contains(x, y) ? float(surface.sample(x, y) + origin.z()) : NAN;
    }
  });
  const RasterGeoreference crs_frame{describe_crs(fmt::format("EPSG:{}", o.site.epsg)).wkt, Eigen::Vector3d::Zero()};
  write_dtm_geotiff(path, truth, crs_frame, {.cog = false, .compression = "DEFLATE"});
}

// One pose per line: the depth file's name, then tx ty tz qx qy qz qw (camera ->
// site frame, metres; the TUM RGB-D trajectory layout with the file name in place
// of the time stamp), as 'strata import depth --poses' reads it.
void write_depth_poses(const fs::path& file, const std::vector<std::string>& names,
                       const std::vector<Eigen::Isometry3d>& poses, const std::string& what) {
  synthetic::TextFile t(file);
  t.out() << "# " << what << ": camera (x right, y down, z forward) -> site frame, metres\n"
          << "# file tx ty tz qx qy qz qw\n";
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Eigen::Quaterniond q(poses[i].linear());
    const Eigen::Vector3d& p = poses[i].translation();
    t.out() << fmt::format("{} {:.6f} {:.6f} {:.6f} {:.9f} {:.9f} {:.9f} {:.9f}\n", names[i], p.x(), p.y(), p.z(),
                           q.x(), q.y(), q.z(), q.w());
  }
  t.close();
}

// The simulated depth sequence of layer k (docs/range.md, "Synthetic depth
// sequences"): depth/L<k>/depth/<nnnn>.png (16-bit grey, millimetres, 0 = no
// return), colour/<nnnn>.png (8-bit RGB, the same pixels), intrinsics.txt, poses_true.txt and
// poses_recorded.txt (the drifting poses a device's tracking would record).
void write_layer_depth(const synthetic::Scene& scene, int k, const fs::path& dir, SyntheticExcavationSummary& summary) {
  using namespace synthetic;
  const auto& o = scene.options();
  const auto& d = o.depth;
  const std::string layer = fmt::format("L{}", k + 1);
  const fs::path out = dir / "depth" / layer;
  fs::create_directories(out / "depth");
  fs::create_directories(out / "colour");
  {
    TextFile t(out / "intrinsics.txt");
    t.out() << fmt::format("# simulated depth camera of {}: pixels, (0, 0) the centre of the top-left pixel, "
                           "no distortion; depth noise one sigma = {} z^2 (z in metres)\n",
                           layer, d.noise_k);
    t.out() << fmt::format("width {}\nheight {}\nfx {}\nfy {}\ncx {}\ncy {}\n", d.width, d.height, d.focal_px,
                           d.focal_px, 0.5 * (d.width - 1), 0.5 * (d.height - 1));
    t.close();
  }
  const auto plan = plan_depth_sequence(scene, k, o.seed);
  std::vector<std::string> names;
  std::vector<Eigen::Isometry3d> truth, recorded;
  for (std::size_t i = 0; i < plan.size(); ++i) {
    check_cancelled();
    const DepthFrame frame = render_depth_frame(scene, k, plan[i].true_pose,
                                                mix64(o.seed * 7057 + std::uint64_t(k) * 41 + i));
    const std::string name = fmt::format("{:04d}.png", i + 1);
    const cv::Mat depth(d.height, d.width, CV_16UC1, const_cast<std::uint16_t*>(frame.depth_mm.data()));
    cv::Mat rgb(d.height, d.width, CV_8UC3, const_cast<std::uint8_t*>(frame.rgb.data())), bgr;
    cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
    if (!cv::imwrite((out / "depth" / name).string(), depth) || !cv::imwrite((out / "colour" / name).string(), bgr))
      throw IoError(fmt::format("synth: {}: frame {} cannot be written", out.string(), name));
    names.push_back(name);
    truth.push_back(plan[i].true_pose);
    recorded.push_back(plan[i].recorded_pose);
    summary.depth_frames++;
  }
  write_depth_poses(out / "poses_true.txt", names, truth, fmt::format("true poses of the depth frames of {}", layer));
  write_depth_poses(out / "poses_recorded.txt", names, recorded,
                    fmt::format("poses of the depth frames of {} as the device's tracking recorded them (drifting)",
                                layer));
}

// Each recorded layer: bake its lit texture (over the first layer's, for the ground
// around the trench), photograph it, write its truth and its scans. Returns the lines
// of gcp_list.txt.
std::vector<std::string> record_layers(const synthetic::Scene& scene, const SyntheticExcavationOptions& o,
                                       const Intrinsics& intrinsics, const std::vector<Eigen::Vector3d>& surveyed,
                                       const fs::path& dir, SyntheticExcavationSummary& summary) {
  using namespace synthetic;
  const Eigen::Vector3d origin = site_origin(o);
  std::vector<std::string> gcp_lines;
  std::vector<std::string> scan_lines;  // of scans.csv
  std::unique_ptr<LayerTexture> ground;
  for (int k = 0; k < scene.layers(); ++k) {
    check_cancelled();
    const std::string layer = fmt::format("L{}", k + 1);
    fs::create_directories(dir / "photos" / layer);
    fs::create_directories(dir / "truth" / layer);
    const Lighting light = session_lighting(scene, k);
    const Stopwatch bake;
    auto texture = std::make_unique<LayerTexture>(scene, k, light, o.render.texel, ground.get());
    log::debug("synth: {} texture baked in {:.2f} s", layer, bake.seconds());
    const auto plan = plan_photos(scene, k, intrinsics);
    for (const auto& v : photograph_layer(scene, k, *texture, light, plan, intrinsics, surveyed, o, dir))
      gcp_lines.insert(gcp_lines.end(), v.begin(), v.end());
    summary.photos += int(plan.size());
    write_true_cameras(plan, origin, dir / "truth" / layer);
    write_truth_surface(scene, k, o, dir / "truth" / layer / "surface.tif");
    if (k == 0) ground = std::move(texture);
    if (o.scans.enabled) write_layer_scans(scene, k, dir, scan_lines, summary);
    if (o.depth.enabled) write_layer_depth(scene, k, dir, summary);
  }
  if (o.scans.enabled) {
    TextFile csv(dir / "scans.csv");
    csv.out() << "layer,file,transform,sigma_m,station_E,station_N,station_Z,yaw_rad,points\n";
    for (const auto& l : scan_lines) csv.out() << l << "\n";
    csv.close();
  }
  return gcp_lines;
}

void write_gcp_list(const std::string& crs, const std::vector<std::string>& lines, const fs::path& path) {
  synthetic::TextFile gcp(path);
  gcp.out() << crs << "\n";
  for (const auto& l : lines) gcp.out() << l << "\n";
  gcp.close();
}

// The limit of excavation as the surveyor laid it out: a field record, used by
// `strata volume --outline` (nothing outside it was dug).
void write_trench_outline(const synthetic::Scene& scene, const SyntheticExcavationOptions& o, const fs::path& path) {
  const Eigen::Vector3d origin = site_origin(o);
  const double e0 = origin.x() + scene.trench_x0(), e1 = origin.x() + scene.trench_x1();
  const double n0 = origin.y() + scene.trench_y0(), n1 = origin.y() + scene.trench_y1();
  synthetic::TextFile outline(path);
  outline.out() << fmt::format(
      "{{\"type\": \"FeatureCollection\", \"crs\": {{\"type\": \"name\", \"properties\": {{\"name\": "
      "\"urn:ogc:def:crs:EPSG::{}\"}}}},\n \"features\": [{{\"type\": \"Feature\", \"properties\": "
      "{{\"name\": \"trench\"}}, \"geometry\": {{\"type\": \"Polygon\", \"coordinates\": "
      "[[[{:.4f}, {:.4f}], [{:.4f}, {:.4f}], [{:.4f}, {:.4f}], [{:.4f}, {:.4f}], [{:.4f}, {:.4f}]]]}}}}]}}\n",
      o.site.epsg, e0, n0, e1, n0, e1, n1, e0, n1, e0, n0);
  outline.close();
}

// Volumes removed, per excavated unit.
void write_removed_volumes(const synthetic::Scene& scene, const fs::path& path, SyntheticExcavationSummary& summary) {
  synthetic::TextFile units(path);
  units.out() << "unit,volume_m3,area_m2,mean_thickness_m,max_thickness_m\n";
  for (int k = 1; k < scene.layers(); ++k) {
    const UnitVolume v = removed_volume(scene.surface(k - 1), scene.surface(k));
    SyntheticExcavationSummary::UnitVolume u;
    u.unit = scene.layer_unit_code(k - 1);
    u.volume_m3 = v.volume;
    u.area_m2 = v.area;
    u.mean_thickness_m = v.area > 0 ? v.volume / v.area : 0;
    u.max_thickness_m = v.max;
    summary.units.push_back(u);
    units.out() << fmt::format("{},{:.9g},{:.9g},{:.9g},{:.9g}\n", u.unit, u.volume_m3, u.area_m2,
                               u.mean_thickness_m, u.max_thickness_m);
  }
  units.close();
}

// Finds planted in the removed units, surveyed like the markers; the truth names
// each one's unit and whether the register was planted wrong.
void write_finds(const synthetic::Scene& scene, const SyntheticExcavationOptions& o, const fs::path& dir,
                 SyntheticExcavationSummary& summary) {
  using namespace synthetic;
  const Eigen::Vector3d origin = site_origin(o);
  Rng find_survey(o.seed ^ 0xF1D55EB7ull);
  TextFile truth(dir / "truth" / "finds.csv"), meas(dir / "finds.csv");
  truth.out() << "id,E,N,Z,true_unit,recorded_unit,planted_contradiction,depth_m,clearance_m\n";
  meas.out() << "id,E,N,Z,unit,type,description\n";
  for (const auto& f : plant_finds(scene, o.seed)) {
    const Eigen::Vector3d t = f.position + origin;
    const Eigen::Vector3d s =
        t + o.site.survey_sigma * Eigen::Vector3d(find_survey.normal(), find_survey.normal(), find_survey.normal());
    truth.out() << fmt::format("{},{:.6f},{:.6f},{:.6f},{},{},{},{:.4f},{:.4f}\n", f.id, t.x(), t.y(), t.z(),
                               f.true_unit, f.recorded_unit, f.contradiction() ? 1 : 0, f.depth_m, f.clearance_m);
    meas.out() << fmt::format("{},{:.4f},{:.4f},{:.4f},{},{},{}\n", f.id, s.x(), s.y(), s.z(), f.recorded_unit,
                              csv_field(f.type), csv_field(f.description));
    summary.finds++;
    summary.planted_contradictions += f.contradiction() ? 1 : 0;
  }
  truth.close();
  meas.close();
}

// Stratigraphy and layers.
void write_stratigraphy(const synthetic::Scene& scene, const fs::path& dir) {
  using namespace synthetic;
  TextFile units(dir / "units.csv");
  units.out() << "code,type,description\n";
  for (const auto& u : scene.units())
    units.out() << csv_field(u.code) << ',' << csv_field(u.type) << ',' << csv_field(u.description) << '\n';
  units.close();
  TextFile rel(dir / "relations.csv");
  rel.out() << "a,relation,b\n";
  for (const auto& r : scene.relations()) rel.out() << r.a << ',' << r.relation << ',' << r.b << '\n';
  rel.close();
  TextFile layers(dir / "layers.csv");
  layers.out() << "layer,unit,captured_at,photos_dir\n";
  for (int k = 0; k < scene.layers(); ++k)
    layers.out() << fmt::format("L{},{},{},photos/L{}\n", k + 1, scene.layer_unit_code(k), session_time(k, 0), k + 1);
  layers.close();
}

// site.json: the site, its layers, camera, markers and scans, for the reader of the
// dataset.
void write_site_json(const synthetic::Scene& scene, const SyntheticExcavationOptions& o, const Intrinsics& intrinsics,
                     const fs::path& path) {
  using namespace synthetic;
  const auto& site = o.site;
  const Eigen::Vector3d origin = site_origin(o);
  nlohmann::ordered_json j;
  j["crs"] = fmt::format("EPSG:{}", site.epsg);
  j["origin"] = {origin.x(), origin.y(), origin.z()};
  j["seed"] = o.seed;
  const double cx = 0.5 * (scene.trench_x0() + scene.trench_x1()), cy = 0.5 * (scene.trench_y0() + scene.trench_y1());
  j["trench"] = {{"min_E", origin.x() + scene.trench_x0()},
                 {"min_N", origin.y() + scene.trench_y0()},
                 {"max_E", origin.x() + scene.trench_x1()},
                 {"max_N", origin.y() + scene.trench_y1()},
                 {"size_E_m", site.trench_size_e},
                 {"size_N_m", site.trench_size_n},
                 {"ground_Z", origin.z() + scene.surface(0).sample(cx, cy)}};
  j["layers"] = nlohmann::json::array();
  for (int k = 0; k < scene.layers(); ++k)
    j["layers"].push_back({{"name", fmt::format("L{}", k + 1)},
                           {"unit", scene.layer_unit_code(k)},
                           {"captured_at", session_time(k, 0)},
                           {"photos", fmt::format("photos/L{}", k + 1)},
                           {"truth", fmt::format("truth/L{}", k + 1)}});
  j["camera"] = {{"make", kMake},
                 {"model", camera_name(o)},
                 {"lens", to_string(intrinsics.model)},
                 {"exif", o.photos.exif},
                 {"sensor_width_mm", o.photos.sensor_width_mm},
                 {"width", intrinsics.width},
                 {"height", intrinsics.height},
                 {"focal_mm", focal_mm(intrinsics, o.photos.sensor_width_mm)}};
  const bool quadrant = site.marker_pattern == SyntheticExcavationOptions::Site::MarkerPattern::quadrant;
  j["markers"] = {{"pattern", quadrant ? "quadrant" : "aruco"},
                  {"dictionary", quadrant ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json("DICT_4X4_50")},
                  {"size_m", site.marker_size},
                  {"count", site.markers},
                  {"check", site.check_markers},
                  {"survey_sigma_m", site.survey_sigma}};
  if (o.depth.enabled)
    j["depth"] = {{"dir", "depth"},
                  {"frames", o.depth.frames},
                  {"width", o.depth.width},
                  {"height", o.depth.height},
                  {"focal_px", o.depth.focal_px},
                  {"noise_k", o.depth.noise_k},
                  {"depth_scale_m", 0.001},
                  {"edge_offset_m", o.depth.edge_offset_m},
                  {"aim_share", o.depth.aim_share},
                  {"drift_rotation_mrad", o.depth.drift_rotation_mrad},
                  {"drift_translation_m", o.depth.drift_translation_m},
                  {"drift_bias_mrad", o.depth.drift_bias_mrad}};
  if (o.scans.enabled)
    j["scans"] = {{"csv", "scans.csv"},
                  {"stations", o.scans.stations},
                  {"step_mrad", o.scans.step_mrad},
                  {"sigma_m", o.scans.sigma_m},
                  {"height_m", o.scans.height_m},
                  {"crop_margin_m", o.scans.crop_margin_m},
                  {"target_sigma_m", o.scans.target_sigma_m}};
  j["generator"] = {{"name", "strata synth"}, {"version", "0.1.0"}};
  TextFile json(path);
  json.out() << j.dump(2) << "\n";
  json.close();
}

void write_dataset(const SyntheticExcavationOptions& o, const fs::path& dir, SyntheticExcavationSummary& summary) {
  using namespace synthetic;
  log::info("synth: building the site (seed {}, {} stages)", o.seed, o.site.stages);
  Stopwatch step;
  const Scene scene(o);
  log::debug("synth: scene built in {:.2f} s", step.seconds());
  const Intrinsics intrinsics = make_intrinsics(o);
  fs::create_directories(dir / "truth");
  const std::vector<Eigen::Vector3d> surveyed = write_markers(scene, o, dir);
  const std::vector<std::string> gcp_lines = record_layers(scene, o, intrinsics, surveyed, dir, summary);
  write_gcp_list(fmt::format("EPSG:{}", o.site.epsg), gcp_lines, dir / "gcp_list.txt");
  write_trench_outline(scene, o, dir / "trench_outline.geojson");
  summary.marker_observations = int(gcp_lines.size());
  summary.markers = int(scene.markers().size());
  summary.layers = scene.layers();
  write_removed_volumes(scene, dir / "truth" / "units.csv", summary);
  write_finds(scene, o, dir, summary);
  write_stratigraphy(scene, dir);
  write_site_json(scene, o, intrinsics, dir / "site.json");
}

}  // namespace

SyntheticExcavationOptions SyntheticExcavationOptions::preset(Size size) {
  SyntheticExcavationOptions o;
  if (size == Size::full) {
    o.photos.per_layer = 40;
    o.photos.width = 2400;
    o.photos.height = 1600;
    o.render.height_cell = 0.0025;
    o.render.texel = 0.00125;  // about the ground sampling distance at 1.5-2 m
  } else {
    // 12 photos at 800 px proved too sparse to align (neighbours 50-108 deg apart,
    // nadir overlap under 50 %, markers 20-30 px): 20 photos at 1000 px is the
    // smallest set that aligns every photo (docs/sfm.md).
    o.photos.per_layer = 20;
    o.photos.width = 1000;
    o.photos.height = 667;
  }
  return o;
}

void SyntheticExcavationOptions::validate() const {
  require(site.epsg > 0, "site.epsg", site.epsg, "a positive EPSG code");
  require(site.trench_size_e >= 1 && site.trench_size_e <= 20, "site.trench_size_e", site.trench_size_e, "1..20 m");
  require(site.trench_size_n >= 1 && site.trench_size_n <= 20, "site.trench_size_n", site.trench_size_n, "1..20 m");
  require(site.stages >= 1 && site.stages <= 8, "site.stages", site.stages, "1..8");
  require(site.min_unit_thickness >= 0.01, "site.min_unit_thickness", site.min_unit_thickness, ">= 0.01 m");
  require(site.max_unit_thickness >= site.min_unit_thickness && site.max_unit_thickness <= 1.0,
          "site.max_unit_thickness", site.max_unit_thickness, "between site.min_unit_thickness and 1 m");
  require(site.markers >= 4 && site.markers <= 12, "site.markers", site.markers, "4..12");
  require(site.check_markers >= 0 && site.check_markers <= site.markers - 3, "site.check_markers",
          site.check_markers, "0..markers-3 (3 control points at least)");
  require(site.marker_size >= 0.05 && site.marker_size <= 0.5, "site.marker_size", site.marker_size, "0.05..0.5 m");
  require(site.survey_sigma >= 0 && site.survey_sigma <= 0.1, "site.survey_sigma", site.survey_sigma, "0..0.1 m");
  require(photos.per_layer >= 3 && photos.per_layer <= 500, "photos.per_layer", photos.per_layer, "3..500");
  require(photos.width >= 64 && photos.width <= 10000, "photos.width", photos.width, "64..10000 pixels");
  require(photos.height >= 64 && photos.height <= 10000, "photos.height", photos.height, "64..10000 pixels");
  require(photos.focal_ratio >= 0.5 && photos.focal_ratio <= 2.0, "photos.focal_ratio", photos.focal_ratio, "0.5..2");
  require(photos.sensor_width_mm > 1 && photos.sensor_width_mm <= 100, "photos.sensor_width_mm",
          photos.sensor_width_mm, "1..100 mm");
  require(photos.fisheye_diagonal_deg >= 90 && photos.fisheye_diagonal_deg <= 170, "photos.fisheye_diagonal_deg",
          photos.fisheye_diagonal_deg, "90..170 degrees");
  require(photos.jpeg_quality >= 1 && photos.jpeg_quality <= 100, "photos.jpeg_quality", photos.jpeg_quality, "1..100");
  require(photos.noise_sigma >= 0 && photos.noise_sigma <= 20, "photos.noise_sigma", photos.noise_sigma, "0..20 grey levels");
  require(render.height_cell >= 0.001 && render.height_cell <= 0.01, "render.height_cell", render.height_cell, "0.001..0.01 m");
  require(render.texel >= 0.0005 && render.texel <= 0.01, "render.texel", render.texel, "0.0005..0.01 m");
  require(render.edge_samples >= 0 && render.edge_samples <= 8, "render.edge_samples", render.edge_samples, "0..8");
  require(render.truth_margin >= 0 && render.truth_margin <= 1.1, "render.truth_margin", render.truth_margin,
          "0..1.1 m (the scene's fine grid reaches 1.2 m around the trench)");
  require(render.truth_cell >= 0.001 && render.truth_cell <= 0.05, "render.truth_cell", render.truth_cell, "0.001..0.05 m");
  require(render.threads >= 0 && render.threads <= 1024, "render.threads", render.threads, "0 (all cores)..1024");
  require(scans.stations >= 2 && scans.stations <= 3, "scans.stations", scans.stations, "2..3");
  require(scans.step_mrad >= 0.5 && scans.step_mrad <= 20, "scans.step_mrad", scans.step_mrad, "0.5..20 mrad");
  require(scans.sigma_m >= 0 && scans.sigma_m <= 0.05, "scans.sigma_m", scans.sigma_m, "0..0.05 m");
  require(scans.target_sigma_m >= 0 && scans.target_sigma_m <= 0.05, "scans.target_sigma_m", scans.target_sigma_m,
          "0..0.05 m");
  require(scans.height_m >= 0.5 && scans.height_m <= 3, "scans.height_m", scans.height_m, "0.5..3 m");
  require(scans.crop_margin_m >= 0 && scans.crop_margin_m <= 1, "scans.crop_margin_m", scans.crop_margin_m,
          "0..1 m (inside the scene's fine grid)");
  require(depth.frames >= 8 && depth.frames <= 1000, "depth.frames", depth.frames, "8..1000");
  require(depth.width >= 32 && depth.width <= 4096, "depth.width", depth.width, "32..4096 pixels");
  require(depth.height >= 32 && depth.height <= 4096, "depth.height", depth.height, "32..4096 pixels");
  require(depth.focal_px >= 0.2 * depth.width && depth.focal_px <= 10.0 * depth.width, "depth.focal_px",
          depth.focal_px, "0.2..10 x depth.width pixels");
  require(depth.noise_k >= 0 && depth.noise_k <= 0.05, "depth.noise_k", depth.noise_k, "0..0.05 1/m");
  require(depth.min_depth_m >= 0.05 && depth.min_depth_m < depth.max_depth_m, "depth.min_depth_m",
          depth.min_depth_m, "0.05 m..depth.max_depth_m");
  require(depth.max_depth_m <= 65.0, "depth.max_depth_m", depth.max_depth_m, "at most 65 m (16-bit millimetres)");
  require(depth.height_m >= 0.3 && depth.height_m <= 3, "depth.height_m", depth.height_m, "0.3..3 m");
  require(depth.edge_offset_m >= 0 && depth.edge_offset_m <= 1, "depth.edge_offset_m", depth.edge_offset_m,
          "0..1 m (inside the scene's fine grid)");
  require(depth.aim_share >= 0 && depth.aim_share <= 0.95, "depth.aim_share", depth.aim_share, "0..0.95");
  require(depth.drift_rotation_mrad >= 0 && depth.drift_rotation_mrad <= 20, "depth.drift_rotation_mrad",
          depth.drift_rotation_mrad, "0..20 mrad");
  require(depth.drift_translation_m >= 0 && depth.drift_translation_m <= 0.05, "depth.drift_translation_m",
          depth.drift_translation_m, "0..0.05 m");
  require(std::abs(depth.drift_bias_mrad) <= 20, "depth.drift_bias_mrad", depth.drift_bias_mrad, "-20..20 mrad");
  constexpr double kGridMarginBoth = 2 * 1.2;  // metres: fine grid margin, both sides (scene.cpp)
  const double nodes = (site.trench_size_e + kGridMarginBoth) * (site.trench_size_n + kGridMarginBoth) /
                       (render.height_cell * render.height_cell);
  require(nodes <= double(kMaxGridNodes), "render.height_cell", render.height_cell,
          "coarse enough for at most 80 million height nodes per layer");
  const double texels = nodes * std::pow(render.height_cell / render.texel, 2);
  require(texels <= 4.0 * double(kMaxGridNodes), "render.texel", render.texel,
          "coarse enough for at most 320 million texels per layer");
}

SyntheticExcavationSummary generate_excavation(const SyntheticExcavationOptions& options, const fs::path& out_dir) {
  const Stopwatch clock;
  options.validate();
  std::error_code ec;
  if (fs::exists(out_dir)) {
    if (!fs::is_directory(out_dir)) throw InputError("synth: " + out_dir.string() + " exists and is not a folder");
    if (!fs::is_empty(out_dir))
      throw InputError("synth: output folder " + out_dir.string() + " is not empty; choose a new or empty folder");
  }
  const fs::path target = fs::absolute(out_dir).lexically_normal();
  const fs::path parent = target.has_filename() ? target.parent_path() : target.parent_path().parent_path();
  const std::string name = (target.has_filename() ? target : target.parent_path()).filename().string();
  fs::create_directories(parent, ec);
  if (ec) throw IoError("synth: cannot create " + parent.string() + ": " + ec.message());
  // Written beside the target and moved into place at the end: a failure or an
  // interruption never leaves a half-written dataset under the requested name.
  const fs::path partial = parent / fmt::format(".{}.partial-{}", name, ::getpid());
  fs::remove_all(partial, ec);
  fs::create_directories(partial, ec);
  if (ec) throw IoError("synth: cannot create " + partial.string() + ": " + ec.message());

  SyntheticExcavationSummary summary;
  summary.out_dir = parent / name;
  try {
    with_threads(options.render.threads, [&] { write_dataset(options, partial, summary); });
    if (fs::exists(summary.out_dir)) fs::remove(summary.out_dir);  // checked empty above
    fs::rename(partial, summary.out_dir);
  } catch (...) {
    fs::remove_all(partial, ec);
    throw;
  }
  summary.seconds = clock.seconds();
  return summary;
}

}  // namespace strata
