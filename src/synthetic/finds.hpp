#pragma once
// Finds planted in the synthetic excavation (internal to strata_synthetic): points
// well inside each removed unit's solid, the true unit known, and a few recorded in
// the wrong unit on purpose, to test `strata finds`.
#include "synthetic/scene.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace strata::synthetic {

struct PlantedFind {
  std::string id;             // "F01", ...
  std::string true_unit;      // unit whose solid holds the point
  std::string recorded_unit;  // what the finds register says; differs when planted wrong
  std::string type, description;
  Eigen::Vector3d position;   // metres, site frame, true
  double depth_m = 0;         // below the unit's top surface at (x, y)
  double clearance_m = 0;     // vertical room to the unit's top and bottom within kFindClearRadius
  bool contradiction() const { return true_unit != recorded_unit; }
};

// Finds per removed unit, planted contradictions in all (each inside a unit, recorded
// in the next unit down: an adjacent unit, the mistake a register makes).
inline constexpr int kFindsPerUnit = 4;
inline constexpr int kPlantedContradictions = 2;
// A find lies where its unit is at least 2 x kFindMinClearance thick everywhere
// within kFindClearRadius, at mid-depth: 5 cm from either surface is far beyond
// a 1 cm voxel and the 2 cm tolerance of `strata finds`.
inline constexpr double kFindMinClearance = 0.05;  // metres
inline constexpr double kFindClearRadius = 0.10;   // metres

std::vector<PlantedFind> plant_finds(const Scene& scene, std::uint64_t seed);

}  // namespace strata::synthetic
