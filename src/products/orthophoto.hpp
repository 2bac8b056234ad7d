#pragma once
// True orthophoto of a layer.
//
// Every DTM cell is coloured from photos that actually see it, at the height of
// the DTM's local median (`rectify_median_radius_m`), with the colour averaged
// over the photo pixels the cell covers (a mipmap of the photo, `antialias`):
//  1. visibility: each photo gets a z-buffer of the DTM surface (the DTM drawn as
//     triangles at a reduced resolution); a cell is visible when its depth along
//     the view matches the buffer, so trench sides and stones do not smear onto
//     the floor behind them;
//  2. view choice: each cell keeps its best `candidates` views by projected
//     resolution, score = cos(angle to the surface normal) * f / depth (photo
//     pixels per metre of surface), lowered near the photo border; a Potts
//     smoothness term (iterated conditional modes) groups cells into regions
//     of one view so that seams are few;
//  3. radiometric balance: one gain per photo and channel, solved by linear least
//     squares on the log colour ratios of every pair of views that see the same
//     cells (El-Hakim, Beraldin & Blais 1998 style exposure equalisation);
//  4. blending: the region masks are feathered (box filter, twice) so seams fade
//     over `feather_m`.
#include "core/cache_key.hpp"
#include "geometry/camera.hpp"
#include "products/dtm.hpp"
#include "geometry/raster.hpp"

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace strata {

// One posed photo. Either `photo` is read from disk (original pixels, EXIF
// orientation ignored, as the camera model expects) or `rgb` holds it in memory.
struct OrthoView {
  std::string name;
  Camera camera;                  // site frame
  std::filesystem::path photo;
  std::vector<std::uint8_t> rgb;  // optional: interleaved RGB, intrinsics.width x height
};

struct OrthoOptions {
  double depth_buffer_scale = 0.25;  // z-buffer size relative to the photo, (0, 1]
  double depth_tolerance_m = 0.005;  // metres, added to the buffer's own depth uncertainty
  double max_view_angle_deg = 75;    // views more oblique to the surface than this are not used
  double border_px = 4;              // photo pixels near the edge that are never sampled
  int candidates = 4;                // best views kept per cell, [1, 16]
  double smoothness = 0.6;           // Potts weight against the relative score, >= 0
  int smoothing_iterations = 5;      // ICM sweeps
  double feather_m = 0.02;           // metres, half-width of the blend across seams
  // Surface normals (view angle test, score, depth tolerance) are taken from the
  // DTM smoothed over about this radius (metres, a tent filter). Central
  // differences over one 5 mm cell turn centimetre noise of the fused surface into
  // 45-70 degree slopes: views are then rejected at random (holes) and scores
  // jump from cell to cell (fragmented regions, seams through the markers).
  // 0 = one-cell central differences.
  double normal_radius_m = 0.02;
  // Heights used to rectify: the median of the DTM within this radius (metres, a
  // square window of 2 round(radius / cell) + 1 cells). Seen from an oblique photo,
  // the fused surface's centimetre noise shifts neighbouring cells by different
  // amounts (noise x tan of the incidence) and warps straight edges: code cells of
  // targets no longer decode, a target's centre moves. A median removes the noise
  // and small spikes and keeps real steps. The DTM product itself is not changed.
  // 0 = rectify on the DTM as it is.
  double rectify_median_radius_m = 0.015;
  bool radiometric_balance = true;   // per-photo gains from the overlaps
  // Colours averaged over the photo pixels each cell covers (a mipmap pyramid of
  // the photo) instead of one bilinear sample at the cell centre, which aliases
  // when a cell spans several photo pixels.
  bool antialias = true;
  Unkeyed<int> threads = 2;          // photos processed in parallel
  // Throws InputError naming the first invalid field.
  void validate() const;
};

struct OrthoSummary {
  int views = 0;                 // photos given
  int views_used = 0;            // photos that colour at least one cell
  std::size_t dtm_cells = 0;     // valid DTM cells
  std::size_t coloured_cells = 0;
  double coverage = 0;           // coloured / valid DTM cells
  double seam_fraction = 0;      // fraction of coloured cells next to another view's region
  std::vector<std::string> view_names;
  std::vector<std::array<double, 3>> gains;  // per view, RGB multiplicative
  std::vector<std::size_t> cells_per_view;   // cells whose region is that view
  double balance_rms_before = 0; // RMS of log colour ratios over overlaps, before gains
  double balance_rms_after = 0;  //   and after
  // Per cell of the grid (NaN where not coloured): the ground size, in metres, of a
  // pixel of the photo that coloured it, along the slope (depth / (f cos incidence)):
  // how finely the photos resolve the surface there, in the worst direction. Cells
  // seen only from afar at grazing angles have pixels much larger than the cell.
  std::vector<float> source_pixel_m;
  double seconds = 0;
};

// The orthophoto on the DTM grid (same cells). Throws ProcessingError when no
// view sees any cell, IoError when a photo cannot be read.
RgbaRaster build_orthophoto(const Dtm& dtm, const std::vector<OrthoView>& views, const OrthoOptions& options,
                            OrthoSummary* summary = nullptr);

}  // namespace strata
