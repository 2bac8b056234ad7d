#pragma once
// Texture atlas of a layer mesh from its photos.
//
//  1. view choice per face: among the views whose photo holds the whole face (away
//     from the border), that face it within `max_view_angle_deg` and in which it is
//     not occluded (a z-buffer of the mesh itself drawn from that view, the
//     orthophoto's DepthBuffer; four points of the face tested), the best
//     `candidates` by score = projected area in photo pixels x cos(view angle):
//     resolution first, frontal views preferred at equal resolution;
//  2. smoothing: iterated conditional modes on a Potts model over the face
//     adjacency (energy = 1 - score / best score + smoothness x share of the
//     face's neighbours on another view), so neighbouring faces keep one photo and
//     seams are few;
//  3. charts: connected faces on the same view, parameterised by their projection
//     into that photo (atlas texels = photo pixels x texel_scale), so a chart is a
//     cut-out of the photo; charts too large for one atlas are split in halves;
//  4. packing: the charts' rectangles, each with a gutter, on shelves in square
//     atlases; texel_scale shrinks until they fit in `max_atlases`;
//  5. colour gains: one gain per photo and channel, fitted by least squares on the
//     log colour ratios of the candidate views of every face several photos see
//     (each candidate's colour: the mean of the photo at the face's four test
//     points), with a regulariser pulling the gains to 1 (fit_colour_gains, the
//     orthophoto's solver), so that seams between charts from photos of different
//     exposure do not show as steps of brightness;
//  6. filling: each texel's surface point (barycentric in its face) is projected
//     with the camera model, distortion included, the photo sampled there
//     (bilinear; a mipmap when a texel spans more than a photo pixel) and its gain
//     applied; the gutter is filled by dilating the charts, so that mipmapping does
//     not bleed.
// Faces no photo sees take a small grey patch (their vertex colours' mean).
#include "dense/dense_mesh.hpp"
#include "products/orthophoto.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace strata {

struct TextureOptions {
  int atlas_size_px = 4096;          // texels, side of a square atlas, [64, 16384]
  int max_atlases = 4;               // atlases at most, >= 1; texel_scale shrinks to fit
  double texel_scale = 1.0;          // atlas texels per photo pixel, (0, 4]: 1 keeps the photos' resolution
  int gutter_px = 4;                 // texels of padding around each chart, >= 1 (mipmaps to level 2 do not bleed)
  double max_view_angle_deg = 75;    // views more oblique to the face than this are not used, (0, 90)
  double depth_buffer_scale = 0.25;  // z-buffer size relative to the photo, (0, 1]
  double depth_tolerance_m = 0.005;  // metres, added to the z-buffer's own depth uncertainty
  double border_px = 4;              // photo pixels near the edge that are never sampled, >= 0
  int candidates = 4;                // best views kept per face, [1, 16]
  double smoothness = 0.5;           // Potts weight against the relative score, >= 0
  int smoothing_iterations = 5;      // ICM sweeps, >= 0
  bool colour_balance = true;        // per-photo colour gains fitted over the faces several photos see
  // Throws InputError naming the first invalid field.
  void validate() const;
};

struct TextureImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // interleaved, sRGB, row-major from the top
};

struct TexturedMesh {
  DenseMesh mesh;                   // vertices duplicated along chart borders; normals kept, no colours
  std::vector<Eigen::Vector2f> uv;  // per vertex, glTF convention: (0, 0) the top-left corner of the atlas
  std::vector<int> face_atlas;      // per face, index into atlases
  std::vector<int> face_view;       // per face, index into the views; -1: the grey patch
  std::vector<TextureImage> atlases;
  // Per view, the colour gains (R, G, B) its texels were multiplied by (all 1 without
  // colour_balance): the check against the photos applies them to each photo.
  std::vector<std::array<double, 3>> view_gains;
};

struct TextureSummary {
  int views = 0;                   // photos given
  int views_used = 0;              // photos that texture at least one face
  std::size_t faces = 0;
  std::size_t textured_faces = 0;  // faces on a photo (the others on the grey patch)
  std::size_t charts = 0;
  int atlases = 0;
  double texel_scale = 0;          // atlas texels per photo pixel, after fitting
  double median_texel_m = 0;       // metres: median ground size of a texel over textured faces
  std::vector<std::string> view_names;
  std::vector<std::size_t> faces_per_view;
  double seam_fraction = 0;        // share of interior edges between faces on different views
  std::vector<std::array<double, 3>> gains;  // per view, RGB multiplicative (all 1 without colour_balance)
  double balance_rms_before = 0;   // RMS of the log colour ratios between candidate views of a face, before gains
  double balance_rms_after = 0;    //   and after
  std::size_t balance_overlaps = 0;  // (face, pair of candidate views) the gains were fitted on
  double seconds = 0;
};

// Throws InputError for a mesh without faces, IoError when a photo cannot be read.
TexturedMesh build_texture_atlas(const DenseMesh& mesh, const std::vector<OrthoView>& views,
                                 const TextureOptions& options, TextureSummary* summary = nullptr);

// The atlas as a JPEG (quality in [1, 100]) or, with quality 0, a PNG file's bytes.
std::string encode_texture_image(const TextureImage& image, int jpeg_quality);

}  // namespace strata
