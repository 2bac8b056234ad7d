#pragma once
// The camera and the hand-held photo sets of each recording session (internal).
#include "geometry/camera.hpp"
#include "synthetic/render.hpp"
#include "synthetic/scene.hpp"

#include <string>
#include <vector>

namespace strata::synthetic {

// One camera body and lens for the whole excavation: focal length from the
// options, a principal point a little off centre, mild barrel distortion.
Intrinsics make_intrinsics(const SyntheticExcavationOptions& options);

struct PlannedPhoto {
  std::string name;         // "L2_0007.jpg": unique across the site
  Camera camera;
  int seconds_after_start;  // seconds since the session started (EXIF time)
  bool oblique;             // taken from the trench edge (else near-vertical)
};

// About 60 % oblique views walking around the trench edge at eye height, then
// near-vertical views in a serpentine over the trench, 1.5-2.5 m above the floor.
std::vector<PlannedPhoto> plan_photos(const Scene& scene, int layer, const Intrinsics& intrinsics);

// Lighting of a session: sun direction and strength, sky, colour temperature.
Lighting session_lighting(const Scene& scene, int layer);

// Local time the session of `layer` started, "YYYY-MM-DDTHH:MM:SS" plus an offset.
std::string session_time(int layer, int seconds_after_start);

}  // namespace strata::synthetic
