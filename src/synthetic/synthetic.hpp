#pragma once
// Synthetic excavations with known truth: the example dataset and the test bed.
//
// generate_excavation() builds a trench in a projected CRS, excavates it in K
// stages, photographs every recorded surface with a hand-held camera (JPEG + EXIF)
// and writes the truth beside the photos: cameras, surface rasters, marker
// coordinates, unit volumes, the Harris matrix of the scene, and finds planted in
// known units (a few recorded in the wrong unit on purpose). The output layout
// is documented in docs/synthetic.md; other modules and the README rely on it.
//
// Public surface: Options (validated once), Summary, one entry function. The
// scene, the renderer and the writers are internal (strata::synthetic).
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace strata {

struct SyntheticExcavationOptions {
  // Preset sizes: `small` is the test scene (4 layers x 20 photos at 1000 x 667),
  // `full` the example dataset (4 layers x 40 photos at 2400 x 1600).
  enum class Size { small, full };
  static SyntheticExcavationOptions preset(Size size);

  std::uint64_t seed = 1;  // every random choice derives from it: same seed, same bytes

  struct Site {
    int epsg = 32636;              // projected CRS of every coordinate written
    double origin_e = 734000.0;    // metres; the site frame is CRS minus this origin
    double origin_n = 4174000.0;   // metres
    double origin_z = 1450.0;      // metres
    double trench_size_e = 4.0;    // metres along easting
    double trench_size_n = 3.0;    // metres along northing
    int stages = 3;                // units removed; layers recorded = stages + 1
    double min_unit_thickness = 0.05;  // metres, thinnest part of a removed unit
    double max_unit_thickness = 0.30;  // metres, thickest part of a removed unit
    int markers = 8;               // coded targets around the trench (6..12)
    int check_markers = 2;         // of which check points (the rest are control)
    double marker_size = 0.15;     // metres, printed square including its white border
    // What is printed on the markers: ArUco codes (found by coded-target detection), or
    // a non-coded chequered quadrant target (two black quadrants, point-symmetric about
    // its centre, inside the same white border) that only clicks or 'markers guide' find.
    enum class MarkerPattern { aruco, quadrant };
    MarkerPattern marker_pattern = MarkerPattern::aruco;
    double survey_sigma = 0.003;   // metres, Gaussian noise of the 'surveyed' markers
  } site;

  struct Photos {
    int per_layer = 12;            // photos of each recorded surface
    int width = 800;               // pixels
    int height = 533;              // pixels
    double focal_ratio = 0.9;      // fx / width (0.8..1.0: a 'normal' lens; brown: ~0.65)
    double sensor_width_mm = 23.5; // APS-C; sets EXIF FocalLength and 35 mm equivalent
    // The lens (docs/cameras.md, "Synthetic lenses"): radial, a mild barrel (k1, k2);
    // brown, a wide DSLR zoom (strong barrel k1 -0.12..-0.20, k2, k3, decentring p1, p2
    // of 1e-4..1e-3); fisheye, an equidistant action camera whose diagonal spans
    // `fisheye_diagonal_deg` (focal_ratio is then derived from it).
    enum class Lens { radial, brown, fisheye } lens = Lens::radial;
    double fisheye_diagonal_deg = 150; // degrees, fisheye only
    bool exif = true;              // false: JPEGs without any EXIF (no focal, no camera name)
    int jpeg_quality = 92;         // 1..100
    double noise_sigma = 1.5;      // 8-bit grey levels of read noise (shot noise added)
  } photos;

  struct Render {
    double height_cell = 0.005;    // metres, height-field node spacing (2..5 mm)
    double texel = 0.0035;         // metres, baked surface texture resolution
    int edge_samples = 4;          // extra rays per pixel on depth edges (0 = none)
    double truth_cell = 0.005;     // metres, cell of the truth surface GeoTIFFs
    double truth_margin = 0.75;    // metres of truth surface around the trench: covers the
                                   // markers (0.3-0.5 m out, 15 cm prints) so the ground
                                   // under them can be checked too
    int threads = 0;               // 0 = all cores
  } render;

  // Simulated terrestrial laser scans of every layer (docs/range.md, "Synthetic
  // scans"); off by default, so the photo dataset is the same with or without them.
  struct Scans {
    bool enabled = false;
    int stations = 3;              // tripod stations per layer at the trench edge (2..3)
    double step_mrad = 2.0;        // angular step in azimuth and elevation: 4-8 mm across the ray at
                                   // the floor 2-4 m away (more along it, at grazing incidence)
    double sigma_m = 0.003;        // metres, range noise, one sigma, Gaussian along the ray
    double height_m = 1.5;         // metres, scanner centre above the ground at the station
    double crop_margin_m = 0.3;    // metres: points kept over the trench and this far around it
    double target_sigma_m = 0.002; // metres, per axis: a marker's centre as the scanner's software finds it
  } scans;

  // A simulated hand-held depth camera (RGB-D) sequence of every layer (docs/range.md,
  // "Synthetic depth sequences"); off by default, so the other files are the same with
  // or without it.
  struct Depth {
    bool enabled = false;
    int frames = 60;               // depth frames per layer, one loop round the trench (8..1000)
    int width = 640;               // pixels
    int height = 480;              // pixels
    double focal_px = 525.0;       // fx = fy, pixels: a 63 x 49 degree field of view at 640 x 480
    double noise_k = 0.0015;       // 1/m: depth noise, one sigma = k z^2 (1.5 mm at 1 m, 6 mm at 2 m)
    double min_depth_m = 0.3;      // metres: nearer than this the sensor returns nothing
    double max_depth_m = 4.0;      // metres: farther than this the sensor returns nothing
    double height_m = 1.2;         // metres: the camera above the ground, held at chest height
    double edge_offset_m = 0.3;    // metres: the path runs this far outside the trench edge
    // The camera aims at the floor this share of the way from the trench centre towards
    // itself (0.3: it sees the near half and the middle; the loop covers the rest). With
    // a wider path (edge_offset_m 1.0), most frames also see a marker or two.
    double aim_share = 0.3;
    // The recorded poses' drift: per frame, one sigma per axis, in the camera frame.
    double drift_rotation_mrad = 1.0;  // milliradians
    double drift_translation_m = 0.002;  // metres
    double drift_bias_mrad = 0.5;  // milliradians per frame about the image's vertical axis (a gyro bias)
  } depth;

  // Throws InputError naming the first invalid field and its value.
  void validate() const;
};

struct SyntheticExcavationSummary {
  struct UnitVolume {
    std::string unit;            // unit code, e.g. "101"
    double volume_m3 = 0;        // volume removed in its stage
    double area_m2 = 0;          // horizontal area where more than 1 mm was removed
    double mean_thickness_m = 0; // volume / area
    double max_thickness_m = 0;
  };
  std::filesystem::path out_dir;
  int layers = 0;
  int photos = 0;
  int markers = 0;
  int marker_observations = 0;   // lines of gcp_list.txt
  int finds = 0;                 // lines of finds.csv (planted in the removed units)
  int planted_contradictions = 0;  // of which recorded in another unit than the true one
  int scans = 0;                 // simulated scan stations written (options.scans)
  std::int64_t scan_points = 0;
  int depth_frames = 0;          // simulated depth frames written (options.depth)
  std::vector<UnitVolume> units; // one per removed unit, in excavation order
  double seconds = 0;            // wall-clock time of the whole generation
};

// Writes the synthetic excavation into out_dir, which must not exist or be empty.
// The files are written into a sibling folder first and moved into place at the
// end, so a failure or Ctrl-C leaves out_dir as it was. Throws InputError for
// invalid options or a non-empty out_dir, IoError when a file cannot be written.
SyntheticExcavationSummary generate_excavation(const SyntheticExcavationOptions& options,
                                               const std::filesystem::path& out_dir);

}  // namespace strata
