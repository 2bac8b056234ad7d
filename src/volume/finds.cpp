#include "volume/finds.hpp"

#include "core/error.hpp"
#include "project/records.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace fs = std::filesystem;

namespace strata {
namespace {

using Index = std::array<int, 3>;

// Voxel index range [lo, hi] per axis holding one label.
struct LabelBox {
  Index lo{}, hi{};
  bool empty = true;
};

std::map<std::int32_t, LabelBox> label_boxes(const LabelVolume& v) {
  std::map<std::int32_t, LabelBox> boxes;
  for (int k = 0; k < v.nz; ++k)
    for (int j = 0; j < v.ny; ++j)
      for (int i = 0; i < v.nx; ++i) {
        const std::int32_t l = v.at(i, j, k);
        if (l == 0) continue;
        LabelBox& b = boxes[l];
        const Index q{i, j, k};
        for (int a = 0; a < 3; ++a) {
          b.lo[a] = b.empty ? q[a] : std::min(b.lo[a], q[a]);
          b.hi[a] = b.empty ? q[a] : std::max(b.hi[a], q[a]);
        }
        b.empty = false;
      }
  return boxes;
}

// Euclidean distance (metres) from p (site frame) to the cube of voxel q.
double cube_distance(const LabelVolume& v, const Eigen::Vector3d& p, const Index& q) {
  double d2 = 0;
  for (int a = 0; a < 3; ++a) {
    const double c = v.min_centre[a] + v.voxel_size_m * q[a];
    const double d = std::max(std::abs(p[a] - c) - 0.5 * v.voxel_size_m, 0.0);
    d2 += d * d;
  }
  return std::sqrt(d2);
}

// Nearest voxel labelled `label` to p, by shells of growing Chebyshev radius r
// around p's voxel c, clipped to the label's box: a voxel r steps from c is at
// least (r - 1) voxel edges from p, so the search stops once the best distance
// found is within that.
double distance_to_label(const LabelVolume& v, const Eigen::Vector3d& p, const Index& c, std::int32_t label,
                         const LabelBox& box) {
  double best = std::numeric_limits<double>::infinity();
  int r = 0;
  for (int a = 0; a < 3; ++a) r = std::max({r, box.lo[a] - c[a], c[a] - box.hi[a]});
  int r_max = 0;
  for (int a = 0; a < 3; ++a) r_max = std::max({r_max, std::abs(box.lo[a] - c[a]), std::abs(box.hi[a] - c[a])});
  for (; r <= r_max; ++r) {
    if (best <= (r - 1) * v.voxel_size_m) break;
    Index lo, hi;
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::max(c[a] - r, box.lo[a]);
      hi[a] = std::min(c[a] + r, box.hi[a]);
    }
    auto visit = [&](int i, int j, int k) {
      if (v.at(i, j, k) == label) best = std::min(best, cube_distance(v, p, {i, j, k}));
    };
    for (int k = lo[2]; k <= hi[2]; ++k)
      for (int j = lo[1]; j <= hi[1]; ++j) {
        if (std::abs(k - c[2]) == r || std::abs(j - c[1]) == r) {
          for (int i = lo[0]; i <= hi[0]; ++i) visit(i, j, k);
          continue;
        }
        // Inside the shell's z and y faces, only its two x faces are new.
        if (c[0] - r >= lo[0]) visit(c[0] - r, j, k);
        if (r > 0 && c[0] + r <= hi[0]) visit(c[0] + r, j, k);
      }
  }
  return best;
}

}  // namespace

void FindCheckOptions::validate() const {
  if (!(tolerance_m >= 0) || !std::isfinite(tolerance_m))
    throw InputError(fmt::format("finds: --tolerance {} must be 0 (automatic) or a positive distance in metres",
                                 tolerance_m));
}

int FindsCheck::conflicts() const {
  return int(std::count_if(finds.begin(), finds.end(), [](const FindPlacement& f) { return f.conflict; }));
}

FindsCheck place_finds(const LabelVolume& v, const std::vector<FindRecord>& finds, const FindCheckOptions& options) {
  options.validate();
  FindsCheck out;
  out.voxel_size_m = v.voxel_size_m;
  out.tolerance_m = options.tolerance_m > 0 ? options.tolerance_m : v.voxel_size_m + kFindSurveyError;
  std::map<std::string, std::int32_t> label_of;
  for (const auto& [label, code] : v.units) label_of[code] = label;
  const auto boxes = label_boxes(v);
  for (const auto& f : finds) {
    FindPlacement p;
    p.find = f;
    const Eigen::Vector3d x = f.position - v.site_origin;  // site frame
    // The voxel holding the point, also when it lies outside the block (the search
    // below starts from it).
    Index c{};
    bool inside = v.voxel_size_m > 0;
    for (int a = 0; a < 3; ++a) {
      const double t = v.voxel_size_m > 0 ? std::floor((x[a] - v.min_centre[a]) / v.voxel_size_m + 0.5) : 0.0;
      c[a] = int(std::clamp(t, -1e9, 1e9));
      inside = inside && c[a] >= 0 && c[a] < (a == 0 ? v.nx : a == 1 ? v.ny : v.nz);
    }
    if (inside) {
      const std::int32_t l = v.at(c[0], c[1], c[2]);
      if (l != 0) {
        const auto it = v.units.find(l);
        p.geometric_unit = it != v.units.end() ? it->second : std::to_string(l);
      }
    }
    const auto label = label_of.find(f.unit);
    const auto box = label == label_of.end() ? boxes.end() : boxes.find(label->second);
    if (box != boxes.end()) p.distance_m = distance_to_label(v, x, c, label->second, box->second);
    if (p.geometric_unit != f.unit) {
      // Without a solid of its own the recorded unit is contradicted only by a point
      // inside another unit's solid.
      p.conflict = p.distance_m ? *p.distance_m > out.tolerance_m : p.geometric_unit.has_value();
    }
    out.finds.push_back(std::move(p));
  }
  return out;
}

std::optional<fs::path> project_voxel_model(Project& project) {
  const auto products = list_products(project.db(), std::nullopt, "voxels");
  if (products.empty()) return std::nullopt;
  const fs::path vdb = project.dir() / products.back().path;
  if (!fs::exists(vdb)) return std::nullopt;
  return vdb;
}

FindsCheck check_project_finds(Project& project, const FindCheckOptions& options) {
  options.validate();
  const auto vdb = project_voxel_model(project);
  if (!vdb) {
    const auto products = list_products(project.db(), std::nullopt, "voxels");
    throw InputError(fmt::format("finds: {} has no voxel model of the units{}; run 'strata volume {}' first",
                                 project.dir().string(),
                                 products.empty() ? "" : " (" + (project.dir() / products.back().path).string() + " is gone)",
                                 project.dir().string()));
  }
  return place_finds(read_label_volume(*vdb), list_finds(project.db()), options);
}

}  // namespace strata
