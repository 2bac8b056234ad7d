#pragma once
// Simulated terrestrial laser scans of each recorded surface (internal to
// strata_synthetic; docs/range.md, "Synthetic scans").
//
// A scanner on a tripod at the trench edge sweeps a regular grid of azimuth and
// elevation (its angular step), each ray cast against the same height field the
// photos are rendered from (render.hpp cast_ray: trench sides, pit edges and stones
// occlude). The range gets Gaussian noise along the ray; the point is written in the
// scanner's own frame, a rotation about the vertical (yaw) and a translation from
// the site frame.
#include "synthetic/scene.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace strata::synthetic {

struct ScanStation {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // metres, site frame: the scanner's centre
  double yaw = 0;                                    // radians: scanner x axis from site east, about +z
  // Scanner frame -> site frame, x_site = R x_scanner + origin (the pose file's matrix).
  Eigen::Matrix4d scanner_to_site() const;
};

// `options.scans.stations` stations per layer outside the trench edge (the middle of
// the south side, then the north-east and north-west corners), scans.height_m above
// the ground there, a few centimetres of jitter and a random yaw per layer.
std::vector<ScanStation> plan_scan_stations(const Scene& scene, int layer, std::uint64_t seed);

struct SimulatedScan {
  ScanStation station;
  std::vector<Eigen::Vector3f> points;  // metres, scanner frame (ranges of metres: float keeps 1 um)
  std::vector<float> intensity;         // 0..1: albedo x cos(incidence)
  std::vector<float> true_range;        // metres, noise-free range of each point (tests)
};

// The rays of the station's angular window over the trench (its footprint plus
// scans.crop_margin_m), keeping the hits inside that footprint. Deterministic for
// a seed, whatever the thread count.
SimulatedScan simulate_scan(const Scene& scene, int layer, const ScanStation& station, std::uint64_t seed);

// The markers the station's scanner measures as registration targets: those whose
// centre it sees (nothing on the ray before it, within range, the print at most 75
// degrees from facing the scanner), in the scanner frame with Gaussian noise of
// scans.target_sigma_m per axis. Deterministic for a seed.
struct TargetObservation {
  std::string name;
  Eigen::Vector3d scanner = Eigen::Vector3d::Zero();  // metres, scanner frame
};
std::vector<TargetObservation> observe_scan_targets(const Scene& scene, int layer, const ScanStation& station,
                                                    std::uint64_t seed);

}  // namespace strata::synthetic
