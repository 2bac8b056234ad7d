#include "synthetic/finds.hpp"

#include "synthetic/noise.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace strata::synthetic {
namespace {

constexpr double kTrenchInset = 0.3;  // metres: no finds in the steep trench sides
constexpr int kTries = 4000;          // candidate points per find before giving up
constexpr double kPi = 3.141592653589793;
constexpr const char* kTypes[] = {"pottery", "bone", "lithic", "charcoal", "metal"};
constexpr const char* kDescriptions[] = {"body sherd", "animal bone fragment", "flint flake", "charcoal lump",
                                         "iron nail"};

// The unit removed between layers k and k+1, at (x, y): the lowest top and the
// highest bottom within kFindClearRadius (centre, and two rings of 8 points).
struct Column {
  double top = 0, bottom = 0;
};
Column column(const Scene& scene, int k, double x, double y) {
  Column c{scene.surface(k).sample(x, y), scene.surface(k + 1).sample(x, y)};
  for (double r : {0.5 * kFindClearRadius, kFindClearRadius})
    for (int a = 0; a < 8; ++a) {
      const double px = x + r * std::cos(a * kPi / 4), py = y + r * std::sin(a * kPi / 4);
      c.top = std::min(c.top, double(scene.surface(k).sample(px, py)));
      c.bottom = std::max(c.bottom, double(scene.surface(k + 1).sample(px, py)));
    }
  return c;
}

}  // namespace

std::vector<PlantedFind> plant_finds(const Scene& scene, std::uint64_t seed) {
  Rng rng(seed ^ 0xF1D5ull);
  std::vector<PlantedFind> out;
  const int units = scene.stages();
  const int total = units * kFindsPerUnit + kPlantedContradictions;
  for (int n = 0; n < total; ++n) {
    const bool wrong = n >= units * kFindsPerUnit;
    const int k = wrong ? (n - units * kFindsPerUnit) % units : n / kFindsPerUnit;
    for (int t = 0; t < kTries; ++t) {
      const double x = rng.uniform(scene.trench_x0() + kTrenchInset, scene.trench_x1() - kTrenchInset);
      const double y = rng.uniform(scene.trench_y0() + kTrenchInset, scene.trench_y1() - kTrenchInset);
      const Column c = column(scene, k, x, y);
      if (c.top - c.bottom < 2 * kFindMinClearance) continue;
      PlantedFind f;
      f.id = fmt::format("F{:02d}", out.size() + 1);
      f.true_unit = scene.layer_unit_code(k);
      f.recorded_unit = wrong ? scene.layer_unit_code(k + 1) : f.true_unit;
      const std::size_t kind = std::size_t(rng.next() % std::size(kTypes));
      f.type = kTypes[kind];
      f.description = kDescriptions[kind];
      const double z = 0.5 * (c.top + c.bottom);
      f.position = {x, y, z};
      f.depth_m = scene.surface(k).sample(x, y) - z;
      f.clearance_m = 0.5 * (c.top - c.bottom);
      out.push_back(f);
      break;
    }
  }
  return out;
}

}  // namespace strata::synthetic
