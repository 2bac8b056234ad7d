// PatchMatch multi-view stereo on the CPU.
//
// Each pixel of the reference view carries a plane hypothesis (depth along the
// camera z axis, normal in the camera frame), following
//  - Bleyer, Rhemann, Rother 2011, "PatchMatch Stereo - Stereo Matching with Slanted
//    Support Windows": random initialisation, spatial plane propagation, refinement;
//  - Galliani, Lasinger, Schindler 2015, "Massively Parallel Multiview Stereopsis by
//    Surface Normal Diffusion" (Gipuma): red/black (checkerboard) updates, so that half
//    the pixels update in parallel from the other half, and best-K cost aggregation;
//  - Schönberger, Zheng, Pollefeys, Frahm 2016, "Pixelwise View Selection for
//    Unstructured Multi-View Stereo": plane-induced homographies, NCC over a window,
//    the perturbation scheme of the refinement step.
// The photometric cost of a plane against one source view is 1 - NCC of the window
// warped by the plane's homography, its samples weighted bilaterally (by distance and
// by grey-level likeness to the centre pixel, Yoon & Kweon 2006); the cost of a hypothesis is the mean of the best
// K source costs, which tolerates occlusion in the other sources.
#include "core/error.hpp"
#include "core/progress.hpp"
#include "dense/internal.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

namespace strata::dense {
namespace {

constexpr float kMaxCost = 2.0f;          // 1 - NCC of anti-correlated windows
constexpr float kMinVariance = 1e-5f;     // gray^2: below this a window is textureless
constexpr int kMaxSources = 16;
constexpr int kMaxWindowSamples = 31 * 31;  // window_radius <= 15, window_step >= 1
constexpr double kSamePlaneDepth = 1e-4;  // relative depth difference of "the same plane"
constexpr float kSamePlaneCos = 0.99995f;   // cos(0.57 deg) between "the same" normals

// splitmix64: small, fast, good enough for PatchMatch sampling; one stream per row.
struct Random {
  std::uint64_t state;
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }  // [0, 1)
  double gaussian() {  // Box-Muller
    const double u1 = std::max(uniform(), 1e-12), u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }
};

// Plane-induced homography from reference pixels to source pixels:
// H = K_s (R_rel + t_rel n^T / c) K_r^-1 for the plane n.X = c (camera frame of the
// reference). Precomputed parts: A = K_s R_rel K_r^-1, b = K_s t_rel.
struct SourceGeometry {
  Eigen::Matrix3d A;
  Eigen::Vector3d b;
  const ViewImage* image;
};

// The view at half resolution: 2 x 2 box average (NaN where any of the four is
// outside the photo), camera scaled with the pixel-centre convention kept.
ViewImage half_resolution(const ViewImage& v) {
  ViewImage out;
  out.camera = v.camera;
  const int w = v.camera.width / 2, h = v.camera.height / 2;
  out.camera.width = w;
  out.camera.height = h;
  out.camera.fx = v.camera.fx / 2;
  out.camera.fy = v.camera.fy / 2;
  out.camera.cx = (v.camera.cx + 0.5) / 2 - 0.5;
  out.camera.cy = (v.camera.cy + 0.5) / 2 - 0.5;
  out.gray.resize(static_cast<std::size_t>(w) * h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      out.gray[static_cast<std::size_t>(y) * w + x] =
          0.25f * (v.gray_at(2 * x, 2 * y) + v.gray_at(2 * x + 1, 2 * y) + v.gray_at(2 * x, 2 * y + 1) +
                   v.gray_at(2 * x + 1, 2 * y + 1));
    }
  }
  return out;
}

class Solver {
 public:
  Solver(const ViewImage& ref, const std::vector<const ViewImage*>& sources, double dmin,
         double dmax, const PatchMatchOptions& opt)
      : ref_(ref), cam_(ref.camera), dmin_(dmin), dmax_(dmax), opt_(opt) {
    STRATA_CHECK(!sources.empty() && static_cast<int>(sources.size()) <= kMaxSources,
                 "patch_match needs 1..{} sources", kMaxSources);
    Eigen::Matrix3d Kr_inv = Eigen::Matrix3d::Identity();
    Kr_inv(0, 0) = 1.0 / cam_.fx;
    Kr_inv(1, 1) = 1.0 / cam_.fy;
    Kr_inv(0, 2) = -cam_.cx / cam_.fx;
    Kr_inv(1, 2) = -cam_.cy / cam_.fy;
    for (const ViewImage* s : sources) {
      const auto& sc = s->camera;
      Eigen::Matrix3d Ks = Eigen::Matrix3d::Identity();
      Ks(0, 0) = sc.fx;
      Ks(1, 1) = sc.fy;
      Ks(0, 2) = sc.cx;
      Ks(1, 2) = sc.cy;
      const Eigen::Matrix3d R_rel = sc.pose.R * cam_.pose.R.transpose();
      const Eigen::Vector3d t_rel = sc.pose.t - R_rel * cam_.pose.t;
      sources_.push_back({Ks * R_rel * Kr_inv, Ks * t_rel, s});
    }
    best_k_ = std::min<int>(opt.best_k, static_cast<int>(sources_.size()));
    cos_max_normal_ = std::cos(opt.max_normal_angle_deg * std::numbers::pi / 180.0);

    const int w = cam_.width, h = cam_.height;
    const auto n = static_cast<std::size_t>(w) * h;
    depth_.assign(n, 0.f);
    normal_.assign(n, Eigen::Vector3f::Zero());
    cost_.assign(n, kMaxCost);
    ref_ok_.assign(n, 0);
    precompute_reference_windows();
    // Bilateral support weights (Yoon & Kweon 2006, as COLMAP weights its NCC): a
    // window sample counts by its distance from the centre and by how much its grey
    // value differs from the centre's, so a window straddling a stone's edge is
    // driven by the side the centre pixel is on and depth edges stay where the
    // photo's edges are instead of fattening the nearer surface.
    const int rad = opt.window_radius, st = opt.window_step;
    const double sc = opt.bilateral_sigma_colour, ss = std::max(1.0, static_cast<double>(rad));
    for (int dy = -rad; dy <= rad; dy += st) {
      for (int dx = -rad; dx <= rad; dx += st) {
        spatial_weight_.push_back(sc > 0 ? static_cast<float>(std::exp(-(dx * dx + dy * dy) / (2 * ss * ss))) : 1.f);
      }
    }
    for (int k = 0; k < kColourLevels; ++k) {
      const double dv = static_cast<double>(k) / (kColourLevels - 1);
      colour_weight_[k] = sc > 0 ? static_cast<float>(std::exp(-dv * dv / (2 * sc * sc))) : 1.f;
    }
    window_samples_ = spatial_weight_.size();
    cache_reference_windows();
  }

  // coarse: the solved half-resolution level of the same views, or null. Its planes
  // initialise this level and only `fine_iterations` sweeps follow, starting with the
  // smaller perturbations of a later iteration.
  DepthMap run(const Solver* coarse = nullptr) {
    const int w = cam_.width, h = cam_.height;
    // Random initialisation (Bleyer 2011 §2.2): depth uniform in inverse depth (even
    // coverage of disparities), normal tilted randomly towards the camera. From a
    // coarse level: the coarse pixel's plane (the same plane in the same camera
    // frame) where it has one that matched, cut with this pixel's ray.
    tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& r) {
      for (int y = r.begin(); y < r.end(); ++y) {
        Random rng{opt_.seed * 0x100000001B3ull + static_cast<std::uint64_t>(y) * 7919u};
        for (int x = 0; x < w; ++x) {
          const std::size_t i = index(x, y);
          if (!ref_ok_[i]) continue;
          depth_[i] = random_depth(rng);
          normal_[i] = random_normal(x, y, rng);
          if (coarse) coarse->transfer_plane(ray(x, y), x / 2, y / 2, depth_[i], normal_[i]);
          cost_[i] = cost(x, y, depth_[i], normal_[i]);
        }
      }
    });

    const int first = coarse ? opt_.iterations - opt_.fine_iterations : 0;
    for (int it = std::max(first, 0); it < opt_.iterations; ++it) {
      check_cancelled();
      for (int colour = 0; colour < 2; ++colour) {
        tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& r) {
          for (int y = r.begin(); y < r.end(); ++y) {
            Random rng{opt_.seed ^ (static_cast<std::uint64_t>(it * 2 + colour + 1) << 40) ^
                       (static_cast<std::uint64_t>(y) * 0x9E3779B1u)};
            for (int x = (y + colour) & 1; x < w; x += 2) update(x, y, it, rng);
          }
        });
      }
    }

    return result();
  }

  // The plane at pixel (xc, yc) of this level, as seen along `ray_fine` (a ray of a
  // finer level's camera: the same camera frame and depth range): writes its depth
  // there and its normal when it matched and cuts the ray inside the range, else
  // leaves both as they are.
  void transfer_plane(const Eigen::Vector3d& ray_fine, int xc, int yc, float& depth,
                      Eigen::Vector3f& normal) const {
    xc = std::min(xc, cam_.width - 1);
    yc = std::min(yc, cam_.height - 1);
    const std::size_t j = index(xc, yc);
    if (!ref_ok_[j] || !(cost_[j] <= opt_.max_cost) || !(depth_[j] > 0)) return;
    const Eigen::Vector3d n = normal_[j].cast<double>();
    const double denom = n.dot(ray_fine);
    if (std::abs(denom) < 1e-9) return;
    const double d = depth_[j] * n.dot(ray(xc, yc)) / denom;
    if (!(d >= dmin_ && d <= dmax_)) return;
    depth = static_cast<float>(d);
    normal = normal_[j];
  }

 private:
  DepthMap result() const {
    const int w = cam_.width, h = cam_.height;
    DepthMap out;
    out.resize(w, h);
    for (std::size_t i = 0; i < depth_.size(); ++i) {
      if (!ref_ok_[i] || cost_[i] > opt_.max_cost || depth_[i] <= 0) continue;
      out.depth[i] = depth_[i];
      for (int k = 0; k < 3; ++k) out.normal[3 * i + k] = normal_[i][k];
      out.confidence[i] = std::clamp(1.0f - cost_[i], 0.0f, 1.0f);
    }
    return out;
  }

  std::size_t index(int x, int y) const { return static_cast<std::size_t>(y) * cam_.width + x; }

  Eigen::Vector3d ray(double x, double y) const {
    return {(x - cam_.cx) / cam_.fx, (y - cam_.cy) / cam_.fy, 1.0};
  }

  // Which reference windows can be matched at all: windows that leave the photo or
  // are textureless (plain variance below kMinVariance) get no depth.
  void precompute_reference_windows() {
    const int w = cam_.width, h = cam_.height, rad = opt_.window_radius, st = opt_.window_step;
    tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& r) {
      for (int y = r.begin(); y < r.end(); ++y) {
        for (int x = 0; x < w; ++x) {
          if (x - rad < 0 || y - rad < 0 || x + rad >= w || y + rad >= h) continue;
          double s = 0, ss = 0;
          int n = 0;
          bool ok = true;
          for (int dy = -rad; dy <= rad && ok; dy += st) {
            for (int dx = -rad; dx <= rad; dx += st) {
              const float v = ref_.gray_at(x + dx, y + dy);
              if (std::isnan(v)) {
                ok = false;
                break;
              }
              s += v;
              ss += static_cast<double>(v) * v;
              ++n;
            }
          }
          if (!ok) continue;
          const double mean = s / n, var = ss / n - mean * mean;
          if (var < kMinVariance) continue;
          const std::size_t i = index(x, y);
          ref_ok_[i] = 1;
        }
      }
    });
  }

  double random_depth(Random& rng) const {
    const double inv = 1.0 / dmax_ + rng.uniform() * (1.0 / dmin_ - 1.0 / dmax_);
    return 1.0 / inv;
  }

  // A normal facing the camera, at most max_normal_angle from the viewing direction.
  Eigen::Vector3f random_normal(int x, int y, Random& rng) const {
    const Eigen::Vector3d view = -ray(x, y).normalized();
    for (int attempt = 0; attempt < 16; ++attempt) {
      Eigen::Vector3d n(rng.gaussian(), rng.gaussian(), rng.gaussian());
      n = (view + 0.8 * n.normalized() * rng.uniform()).normalized();
      if (n.dot(view) >= cos_max_normal_) return n.cast<float>();
    }
    return view.cast<float>();
  }

  bool normal_ok(int x, int y, const Eigen::Vector3f& n) const {
    const Eigen::Vector3d view = -ray(x, y).normalized();
    return n.cast<double>().dot(view) >= cos_max_normal_;
  }

  // The reference side of the weighted NCC at (x, y): normalised weights w_k and
  // weighted, standardised values r_k = w_k (v_k - mean_w) / std_w, so that for a
  // source window s: NCC_w = sum r_k s_k / std_w(s) (sum r_k = 0, sum w_k = 1).
  // False when the weighted window is textureless.
  bool reference_window(int x, int y, float* wk, float* rk) const {
    const int rad = opt_.window_radius, st = opt_.window_step;
    const float centre = ref_.gray_at(x, y);
    float wsum = 0, s1 = 0, s2 = 0;
    int count = 0;
    for (int dy = -rad; dy <= rad; dy += st) {
      const float* row = ref_.gray.data() + index(x - rad, y + dy);
      for (int dx = 0; dx <= 2 * rad; dx += st, ++count) {
        const float v = row[dx];
        const int level = std::min(kColourLevels - 1, static_cast<int>(std::abs(v - centre) * (kColourLevels - 1) + 0.5f));
        const float w = spatial_weight_[count] * colour_weight_[level];
        wk[count] = w;
        rk[count] = v;
        wsum += w;
        s1 += w * v;
        s2 += w * v * v;
      }
    }
    const float mean = s1 / wsum, var = s2 / wsum - mean * mean;
    if (!(var > kMinVariance)) return false;
    const float inv = 1.0f / (wsum * std::sqrt(var));
    for (int k = 0; k < count; ++k) {
      rk[k] = wk[k] * (rk[k] - mean) * inv;
      wk[k] /= wsum;
    }
    return true;
  }

  // Every cost evaluation of a pixel needs its reference window: computed once per
  // pixel and kept when it fits in kReferenceCacheBytes (it does at the usual 1/4 and
  // 1/2 depth-map scales), else recomputed per evaluation.
  void cache_reference_windows() {
    const std::size_t n = ref_ok_.size();
    if (n * window_samples_ * 2 * sizeof(float) > kReferenceCacheBytes) return;
    ref_w_.assign(n * window_samples_, 0.f);
    ref_r_.assign(n * window_samples_, 0.f);
    const int w = cam_.width, h = cam_.height;
    tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& r) {
      for (int y = r.begin(); y < r.end(); ++y) {
        for (int x = 0; x < w; ++x) {
          const std::size_t i = index(x, y);
          if (ref_ok_[i] &&
              !reference_window(x, y, ref_w_.data() + i * window_samples_, ref_r_.data() + i * window_samples_)) {
            ref_ok_[i] = 0;  // its cost would always be kMaxCost
          }
        }
      }
    });
  }

  // Photometric cost of the plane (depth d at pixel (x, y), normal n), best-K mean.
  // Inner loop in float: 25-36 samples of values in [0, 1] lose nothing at float
  // precision, and it is where all the time goes.
  float cost(int x, int y, double d, const Eigen::Vector3f& nf) const {
    const std::size_t i = index(x, y);
    if (!ref_ok_[i] || !(d > 0)) return kMaxCost;
    const Eigen::Vector3d n = nf.cast<double>();
    const Eigen::Vector3d r = ray(x, y);
    const double c = d * n.dot(r);  // plane n.X = c, c < 0 for a plane facing the camera
    if (std::abs(c) < 1e-9) return kMaxCost;
    // n^T K_r^-1 as a row vector.
    const Eigen::Vector3d m(n.x() / cam_.fx, n.y() / cam_.fy,
                            n.z() - n.x() * cam_.cx / cam_.fx - n.y() * cam_.cy / cam_.fy);
    std::array<float, kMaxSources> costs{};
    const int rad = opt_.window_radius, st = opt_.window_step;
    const float* wk;
    const float* rk;
    std::array<float, kMaxWindowSamples> w_local, r_local;
    if (!ref_w_.empty()) {
      wk = ref_w_.data() + i * window_samples_;
      rk = ref_r_.data() + i * window_samples_;
    } else {
      if (!reference_window(x, y, w_local.data(), r_local.data())) return kMaxCost;
      wk = w_local.data();
      rk = r_local.data();
    }
    for (std::size_t s = 0; s < sources_.size(); ++s) {
      const Eigen::Matrix3d H = sources_[s].A + sources_[s].b * m.transpose() / c;
      const Eigen::Vector3f hu = (st * H.col(0)).cast<float>(), hv = (st * H.col(1)).cast<float>();
      const Eigen::Vector3f h0 = (H * Eigen::Vector3d(x - rad, y - rad, 1.0)).cast<float>();
      const ViewImage& img = *sources_[s].image;
      const float wmax = static_cast<float>(img.camera.width) - 1.001f;
      const float hmax = static_cast<float>(img.camera.height) - 1.001f;
      const int w = img.camera.width;
      // The warped window is a convex quadrilateral when the plane stays in front of
      // the source camera, so checking its 4 corners bounds every sample: the inner
      // loop then runs without branches or clamps (the 0.001 px margin absorbs the
      // float rounding of interior samples; a NaN of the photo border propagates into
      // the sums and is caught once at the end).
      const int last = (2 * rad / st);
      bool inside = true;
      for (int corner = 0; corner < 4 && inside; ++corner) {
        const Eigen::Vector3f q = h0 + static_cast<float>((corner & 1) * last) * hu +
                                  static_cast<float>((corner >> 1) * last) * hv;
        if (!(q.z() > 0)) {
          inside = false;
          break;
        }
        const float u = q.x() / q.z(), v = q.y() / q.z();
        inside = u >= 0 && v >= 0 && u <= wmax && v <= hmax;
      }
      if (!inside) {
        costs[s] = kMaxCost;
        continue;
      }
      float sum_s = 0, sum_ss = 0, sum_rs = 0;
      int k = 0;
      Eigen::Vector3f q_row = h0;
      for (int dy = 0; dy <= 2 * rad; dy += st, q_row += hv) {
        Eigen::Vector3f q = q_row;
        for (int dx = 0; dx <= 2 * rad; dx += st, q += hu, ++k) {
          const float iz = 1.0f / q.z();
          const float u = q.x() * iz, v = q.y() * iz;  // inside: the corners were checked
          const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
          const float au = u - u0, av = v - v0;
          const float* p0 = img.gray.data() + static_cast<std::size_t>(v0) * w + u0;
          const float* p1 = p0 + w;
          const float top = p0[0] + au * (p0[1] - p0[0]);
          const float val = top + av * (p1[0] + au * (p1[1] - p1[0]) - top);
          sum_s += wk[k] * val;
          sum_ss += wk[k] * val * val;
          sum_rs += rk[k] * val;
        }
      }
      if (std::isnan(sum_s)) {
        costs[s] = kMaxCost;
        continue;
      }
      const float mean_s = sum_s;  // weights sum to 1
      const float var_s = sum_ss - mean_s * mean_s;
      if (var_s < kMinVariance) {
        costs[s] = kMaxCost;
        continue;
      }
      const float ncc = sum_rs / std::sqrt(var_s);
      costs[s] = 1.0f - std::clamp(ncc, -1.0f, 1.0f);
    }
    const int ns = static_cast<int>(sources_.size());
    std::partial_sort(costs.begin(), costs.begin() + best_k_, costs.begin() + ns);
    float total = 0;
    for (int k = 0; k < best_k_; ++k) total += costs[k];
    return total / best_k_;
  }

  void try_hypothesis(int x, int y, double d, const Eigen::Vector3f& n) {
    if (!(d >= dmin_ && d <= dmax_)) return;
    const std::size_t i = index(x, y);
    // Once a region has converged its neighbours propose (almost) the plane the pixel
    // already has; re-evaluating it cannot lower the cost, so skip it (most of the
    // propagation work of the later iterations).
    if (std::abs(d - depth_[i]) < kSamePlaneDepth * d && n.dot(normal_[i]) > kSamePlaneCos) return;
    const float c = cost(x, y, d, n);
    if (c < cost_[i]) {
      cost_[i] = c;
      depth_[i] = static_cast<float>(d);
      normal_[i] = n;
    }
  }

  void update(int x, int y, int iteration, Random& rng) {
    const std::size_t i = index(x, y);
    if (!ref_ok_[i]) return;
    const int w = cam_.width, h = cam_.height;
    // Spatial propagation: in each of the 4 directions, the best (lowest-cost) plane
    // among the pixels of the other colour at distances 1, 3, 5 (an adaptive
    // checkerboard in the spirit of Gipuma and ACMM, Xu & Tao 2019), re-evaluated at
    // this pixel: depth where the neighbour's plane meets this ray (Bleyer 2011 §2.3).
    static constexpr std::array<std::array<int, 2>, 4> kDirections{{{-1, 0}, {1, 0}, {0, -1}, {0, 1}}};
    static constexpr std::array<int, 3> kDistances{1, 3, 5};
    const Eigen::Vector3d r = ray(x, y);
    for (const auto& dir : kDirections) {
      std::size_t best = 0;
      float best_cost = kMaxCost;
      int bx = 0, by = 0;
      for (int dist : kDistances) {
        const int nx = x + dir[0] * dist, ny = y + dir[1] * dist;
        if (nx < 0 || ny < 0 || nx >= w || ny >= h) break;
        const std::size_t j = index(nx, ny);
        if (ref_ok_[j] && cost_[j] < best_cost) {
          best_cost = cost_[j];
          best = j;
          bx = nx;
          by = ny;
        }
      }
      if (best_cost >= kMaxCost) continue;
      const Eigen::Vector3d nn = normal_[best].cast<double>();
      const double c = depth_[best] * nn.dot(ray(bx, by));
      const double denom = nn.dot(r);
      if (std::abs(denom) < 1e-9) continue;
      try_hypothesis(x, y, c / denom, normal_[best]);
    }

    // Refinement (Schönberger 2016 §4.3): perturbations that shrink with the
    // iterations, plus one fresh random depth early on to escape local minima.
    const double shrink = std::pow(0.5, iteration + 1);
    const double d = depth_[i];
    const Eigen::Vector3f n = normal_[i];
    const double range = (dmax_ - dmin_) * shrink;
    const double dp = std::clamp(d + (rng.uniform() - 0.5) * range, dmin_, dmax_);
    Eigen::Vector3f np =
        (n + static_cast<float>(0.5 * shrink) *
                 Eigen::Vector3f(static_cast<float>(rng.gaussian()), static_cast<float>(rng.gaussian()),
                                 static_cast<float>(rng.gaussian())))
            .normalized();
    const bool np_ok = normal_ok(x, y, np);
    if (iteration == 0) try_hypothesis(x, y, random_depth(rng), n);
    if (np_ok) {
      try_hypothesis(x, y, d, np);
      try_hypothesis(x, y, dp, np);
    } else {
      try_hypothesis(x, y, dp, n);
    }
  }

  const ViewImage& ref_;
  const PinholeCamera& cam_;
  double dmin_, dmax_;
  const PatchMatchOptions& opt_;
  std::vector<SourceGeometry> sources_;
  int best_k_ = 1;
  double cos_max_normal_ = 0;
  std::vector<float> depth_;
  std::vector<Eigen::Vector3f> normal_;
  std::vector<float> cost_;
  std::vector<std::uint8_t> ref_ok_;
  static constexpr int kColourLevels = 256;
  std::vector<float> spatial_weight_;                 // per window sample
  std::size_t window_samples_ = 0;
  static constexpr std::size_t kReferenceCacheBytes = std::size_t{256} << 20;
  std::vector<float> ref_w_, ref_r_;  // per pixel x window sample, when cached
  std::array<float, kColourLevels> colour_weight_{};  // by |grey - centre grey|
};

}  // namespace

std::size_t DepthMap::valid_count() const {
  return static_cast<std::size_t>(std::count_if(depth.begin(), depth.end(), [](float d) { return d > 0; }));
}

DepthMap patch_match(const ViewImage& ref, const std::vector<const ViewImage*>& sources,
                     double depth_min, double depth_max, const PatchMatchOptions& opt) {
  STRATA_CHECK(depth_min > 0 && depth_max > depth_min, "bad depth range [{}, {}]", depth_min,
               depth_max);
  // Coarse to fine: a half-resolution pass (a quarter of the pixels, all iterations)
  // gives every pixel a plane near the surface, so the full resolution needs only
  // `fine_iterations` sweeps to converge from it instead of all from random planes.
  constexpr int kMinCoarseSide = 64;  // below this the coarse level has too few windows
  if (opt.coarse_to_fine && ref.camera.width >= 2 * kMinCoarseSide &&
      ref.camera.height >= 2 * kMinCoarseSide) {
    const ViewImage ref_half = half_resolution(ref);
    std::vector<ViewImage> src_half;
    src_half.reserve(sources.size());
    for (const ViewImage* s : sources) src_half.push_back(half_resolution(*s));
    std::vector<const ViewImage*> src_half_ptr;
    for (const auto& s : src_half) src_half_ptr.push_back(&s);
    Solver coarse(ref_half, src_half_ptr, depth_min, depth_max, opt);
    coarse.run();
    Solver fine(ref, sources, depth_min, depth_max, opt);
    return fine.run(&coarse);
  }
  Solver solver(ref, sources, depth_min, depth_max, opt);
  return solver.run();
}

}  // namespace strata::dense
