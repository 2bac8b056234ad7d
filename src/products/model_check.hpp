#pragma once
// Check of a textured model against the photos it was made from (products.model_check).
//
// The model is rendered from a photo's own camera, the reconstruction's pose and
// intrinsics with the lens distortion, projected exactly as the texturing projects
// (photo_sampling's Projector and the triangle z-buffer, here at the photo's
// resolution or a fraction of it): per rendered pixel the nearest face, the point
// where the pixel's ray meets that face, its barycentric coordinates -> UV -> a
// bilinear sample of the atlas. Compared with the photo at the same pixel (times the
// colour gains the texture gave that photo, TexturedMesh::view_gains), the
// absolute colour differences over the pixels the model covers are summarised as
// median and 90th percentile per channel. Where the texture is right they are the
// photos' own interpolation and noise; a seam on the wrong photo, a misregistered
// chart or a wrong pose shows as larger figures and as lines in the difference image.
#include "products/orthophoto.hpp"
#include "products/texture_atlas.hpp"

#include <Eigen/Core>

#include <array>
#include <cstddef>
#include <string>
#include <vector>

namespace strata {

struct ModelCheckOptions {
  double scale = 1.0;       // rendered pixels per photo pixel, (0, 1]: 1 compares every photo pixel
  double border_px = 4;     // photo pixels near the edge not compared (the texture never samples them), >= 0
  // Site-frame XY polygon (metres; the trench): the `inside` figures count only the
  // pixels whose surface point lies in it. Empty: no restriction; else >= 3 corners.
  std::vector<Eigen::Vector2d> region;
  bool images = false;         // also return the rendered and the difference image
  double difference_gain = 4;  // difference image = |difference| x gain (clamped to 255), >= 1
  // Throws InputError naming the first invalid field.
  void validate() const;
};

// |render - photo| in grey levels (0-255) over a set of pixels.
struct ColourDifference {
  std::size_t pixels = 0;             // pixels compared
  std::array<double, 3> median{};     // per channel R, G, B
  std::array<double, 3> p90{};        // 90th percentile, per channel
  double median_mean = 0, p90_mean = 0;  // of the mean of the three channels' |difference| per pixel
};

struct PhotoCheck {
  std::string view;                   // the photo's name
  ColourDifference all;               // every textured pixel the model covers
  ColourDifference inside;            // those whose surface point is inside options.region (= all without one)
  // Of `all`, the pixels on faces textured from this very photo: the resampling
  // alone (the others add the colour difference between photos and their
  // registration).
  ColourDifference own;
  std::size_t untextured_pixels = 0;  // covered by faces no photo textures (the grey patch): not compared
  TextureImage rendered;              // with options.images: the render (black where no model), scale x photo size
  TextureImage difference;            // with options.images: |difference| x gain per channel, black where not compared
  double seconds = 0;
};

struct ModelCheckSummary {
  std::vector<PhotoCheck> photos;
  ColourDifference all, inside, own;  // pooled over every photo's pixels
  double seconds = 0;
};

// Renders `model` (build_texture_atlas's result, site frame, textured from `views`:
// its face_view indexes them) from each of the views `checked` (indices into
// `views`) and compares with its photo. Throws IoError when a photo cannot be
// read, InputError for invalid options or an index out of range.
ModelCheckSummary check_textured_model(const TexturedMesh& model, const std::vector<OrthoView>& views,
                                       const std::vector<int>& checked, const ModelCheckOptions& options);

}  // namespace strata
