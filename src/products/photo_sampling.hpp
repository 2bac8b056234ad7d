#pragma once
// Photo access shared by the products that colour a surface from posed photos (the
// true orthophoto, the textured layer model): reading a photo as its camera model
// expects it, sampling it (bilinear, optionally over a mipmap), projecting with a
// guard against the lens polynomial folding back, and a z-buffer of triangles drawn
// from a photo's viewpoint for the occlusion test. Internal to strata_products:
// this header includes OpenCV.
#include "geometry/camera.hpp"
#include "geometry/mesh.hpp"
#include "products/orthophoto.hpp"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <cstdint>
#include <limits>
#include <vector>

namespace strata {

// A photo's pixels, interleaved RGB, as a pyramid of 2 x 2 box averages
// (level 0 = the photo). A surface cell usually covers several photo pixels
// (5 mm cells from 1 mm pixels): sampling the photo itself at the cell centre
// would alias (stair-stepped, speckled target edges); sampling the level whose
// pixel matches the cell's footprint averages the pixels the cell covers.
struct PhotoPixels {
  std::vector<cv::Mat> levels;  // CV_8UC3, level l pixel j averages level l-1 pixels 2j, 2j+1

  // Adds coarser levels until a pixel covers `max_footprint_px` photo pixels or the
  // image is a few pixels wide.
  void build_pyramid(double max_footprint_px);

  // Colour at photo pixel (x, y) ((0, 0) = centre of the top-left pixel) averaged
  // over about `footprint_px` photo pixels: bilinear in the two levels around
  // log2(footprint / 2), blended between them (trilinear, as in mipmapping). The
  // level whose pixels are half the footprint, because its 2 x 2 box and the
  // bilinear tent over two of its pixels together already span about one
  // footprint; the level of the whole footprint blurs over two cells (measured on
  // the example: blurred code cells, fewer targets found in the orthophotos).
  // footprint_px <= 1: one bilinear sample of the photo.
  void sample(double x, double y, double footprint_px, std::uint8_t out[3]) const;

 private:
  void bilinear(int level, double x0, double y0, double out[3]) const;
};

// The view's photo (from memory or disk; EXIF orientation ignored, as the camera
// model describes the sensor as stored). Throws IoError when it cannot be read,
// InputError when its size is not its camera's. `stage` starts the messages.
PhotoPixels load_photo(const OrthoView& v, const char* stage);

// Projection with a guard against the radial polynomial folding far-away points
// back into the frame: points beyond the normalised radius of the photo corners
// (plus a margin) are rejected.
struct Projector {
  const Camera& cam;
  double max_r2 = 0;

  explicit Projector(const Camera& c);
  // Returns false when behind the camera or outside the usable cone.
  bool project(const Eigen::Vector3d& X, Eigen::Vector2d& px, double& depth) const;
};

// Depth along the view (metres) of the nearest surface per buffer pixel, the
// buffer being the photo scaled by `scale` in (0, 1]. Triangles are given by their
// photo pixel positions and depths; depth is interpolated as 1/z
// (perspective-correct). With `keep_faces` it also records which triangle is the
// nearest per buffer pixel (the `face` given to draw_triangle), for rendering.
class DepthBuffer {
 public:
  static constexpr float kNoDepth = std::numeric_limits<float>::infinity();
  static constexpr int kNoFace = -1;

  DepthBuffer(const Intrinsics& K, double scale, bool keep_faces = false);
  void draw_triangle(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c, double da,
                     double db, double dc, int face = kNoFace);
  // Nearest depth at photo pixel (x, y) (the buffer pixel holding it, clamped).
  float at(double x, double y) const;
  int width() const { return width_; }
  int height() const { return height_; }
  // The nearest triangle at buffer pixel (bx, by); kNoFace where none was drawn or
  // without keep_faces.
  int face(int bx, int by) const { return faces_.empty() ? kNoFace : faces_[std::size_t(by) * width_ + bx]; }
  // The photo pixel at the centre of buffer pixel b (inverse of the buffer mapping).
  double to_photo(int b) const { return (b + 0.5) / scale_ - 0.5; }
  // Metres of surface one buffer pixel spans at depth d (its own uncertainty).
  double footprint_m(double d) const { return d / (fx_ * scale_); }
  double scale() const { return scale_; }

 private:
  double to_buffer(double p) const { return (p + 0.5) * scale_ - 0.5; }
  int width_ = 0, height_ = 0;
  double scale_ = 1, fx_ = 1;
  std::vector<float> depth_;
  std::vector<int> faces_;  // empty without keep_faces
};

// A mesh's vertices projected into a view: photo pixels and depth along the view
// (metres; -1 where the projector rejects the vertex).
struct ProjectedVertices {
  std::vector<Eigen::Vector2d> px;
  std::vector<double> depth;
  bool in_view(const std::array<int, 3>& f) const {
    return depth[std::size_t(f[0])] > 0 && depth[std::size_t(f[1])] > 0 && depth[std::size_t(f[2])] > 0;
  }
};
ProjectedVertices project_vertices(const DenseMesh& m, const Projector& proj);

// The z-buffer of the mesh's faces whose corners all project, at `scale` of the
// photo; with keep_faces, the face index per buffer pixel.
DepthBuffer mesh_depth_buffer(const DenseMesh& m, const ProjectedVertices& v, const Intrinsics& K, double scale,
                              bool keep_faces = false);

}  // namespace strata
