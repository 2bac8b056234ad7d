#pragma once
// The site model as one self-contained viewer page (three.js and the model inlined):
// built here for `strata export viewer` (a file) and the field station's 3D page (served).
// The scene is build_site_scene's; the page is writer.viewer's (exporters/viewer).
#include "project/project.hpp"

#include <cstddef>
#include <string>

namespace strata {

struct SiteViewerOptions {
  std::string layer;                 // "": every layer and the unit solids; else this layer alone
  std::size_t max_faces = 300000;    // faces per layer mesh at most (simplified above; 0: keep all)
  int coarse_lod = 2;                // level shown first while the full one loads: faces / 4^N (0: none)
  std::string command = "export viewer";  // names the command in warnings and errors
};

// Above this a browser tab needs several times as much memory to decode and upload it.
inline constexpr std::size_t kLargeViewerModelBytes = 150'000'000;

struct SiteViewer {
  std::string html;
  std::size_t first_bytes = 0, detail_bytes = 0;  // the embedded models
  std::size_t layers = 0, units = 0, markers = 0, finds = 0, cameras = 0;
};

// Throws as build_site_scene (InputError when no layer has a dense mesh yet), and
// InputError when libjs-three is missing (checked first, before the slow part).
SiteViewer build_site_viewer(Project& project, const std::string& dir, const SiteViewerOptions& options);

}  // namespace strata
