#include "exporters/cameras/camera_export.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"

#include <Eigen/Geometry>
#include <fmt/format.h>

#include <cstdio>
#include <iterator>
#include <memory>

namespace fs = std::filesystem;

namespace strata {
namespace {

// A text file built in memory, then written through a temporary name and renamed
// into place (core/atomic_file.hpp).
class AtomicFile {
 public:
  explicit AtomicFile(fs::path path) : path_(std::move(path)) {}
  auto out() { return std::back_inserter(buffer_); }
  void commit() {
    write_bytes_atomically(path_, "exporter", std::string_view(buffer_.data(), buffer_.size()),
                           "export.cameras.temp_written");
  }

 private:
  fs::path path_;
  fmt::memory_buffer buffer_;
};

}  // namespace

void write_cameras_csv(const Reconstruction& rec, const Eigen::Vector3d& origin, const fs::path& out) {
  AtomicFile f(out);
  fmt::format_to(f.out(), "image,fx,fy,ppx,ppy,k1,k2,r11,r12,r13,r21,r22,r23,r31,r32,r33,X,Y,Z\n");
  for (const auto& im : rec.images) {
    if (!im.registered) continue;
    const Intrinsics& k = rec.groups.at(im.group).intrinsics;
    const Eigen::Matrix3d& R = im.pose.R;
    const Eigen::Vector3d C = im.pose.centre() + origin;
    fmt::format_to(f.out(), "{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}", im.name, k.fx, k.fy, k.cx, k.cy,
               k.k1, k.k2);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) fmt::format_to(f.out(), ",{:.17g}", R(r, c));
    }
    fmt::format_to(f.out(), ",{:.17g},{:.17g},{:.17g}\n", C.x(), C.y(), C.z());
  }
  f.commit();
}

void write_cameras_lens_csv(const Reconstruction& rec, const Eigen::Vector3d& origin,
                            const fs::path& out) {
  AtomicFile f(out);
  fmt::format_to(f.out(),
             "image,model,fx,fy,ppx,ppy,k1,k2,k3,k4,p1,p2,r11,r12,r13,r21,r22,r23,r31,r32,r33,X,Y,Z\n");
  for (const auto& im : rec.images) {
    if (!im.registered) continue;
    const Intrinsics& k = rec.groups.at(im.group).intrinsics;
    const Eigen::Matrix3d& R = im.pose.R;
    const Eigen::Vector3d C = im.pose.centre() + origin;
    fmt::format_to(f.out(), "{},{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}",
               im.name, to_string(k.model), k.fx, k.fy, k.cx, k.cy, k.k1, k.k2, k.k3, k.k4, k.p1, k.p2);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) fmt::format_to(f.out(), ",{:.17g}", R(r, c));
    }
    fmt::format_to(f.out(), ",{:.17g},{:.17g},{:.17g}\n", C.x(), C.y(), C.z());
  }
  f.commit();
}

void write_colmap_model(const Reconstruction& rec, const fs::path& folder) {
  fs::create_directories(folder);
  {
    AtomicFile f(folder / "cameras.txt");
    fmt::format_to(f.out(), "# Camera list: CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[] (written by strata)\n");
    for (std::size_t g = 0; g < rec.groups.size(); ++g) {
      const Intrinsics& k = rec.groups[g].intrinsics;
      const double cx = k.cx + 0.5, cy = k.cy + 0.5;
      switch (k.model) {
        case CameraModel::radial:
          // OPENCV: fx, fy, cx, cy, k1, k2, p1, p2
          fmt::format_to(f.out(), "{} OPENCV {} {} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} 0 0\n", g + 1,
                     k.width, k.height, k.fx, k.fy, cx, cy, k.k1, k.k2);
          break;
        case CameraModel::brown:
          // FULL_OPENCV: fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6 (k4-k6: the
          // rational model's denominator, zero here)
          fmt::format_to(f.out(),
                     "{} FULL_OPENCV {} {} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} "
                     "{:.17g} 0 0 0\n",
                     g + 1, k.width, k.height, k.fx, k.fy, cx, cy, k.k1, k.k2, k.p1, k.p2, k.k3);
          break;
        case CameraModel::fisheye:
          // OPENCV_FISHEYE: fx, fy, cx, cy, k1, k2, k3, k4
          fmt::format_to(f.out(),
                     "{} OPENCV_FISHEYE {} {} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g}\n",
                     g + 1, k.width, k.height, k.fx, k.fy, cx, cy, k.k1, k.k2, k.k3, k.k4);
          break;
      }
    }
    f.commit();
  }
  {
    AtomicFile f(folder / "images.txt");
    fmt::format_to(f.out(), "# IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME; then an empty 2D point line\n");
    for (std::size_t i = 0; i < rec.images.size(); ++i) {
      const auto& im = rec.images[i];
      if (!im.registered) continue;
      const Eigen::Quaterniond q(im.pose.R);
      fmt::format_to(f.out(), "{} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {} {}\n\n", i + 1, q.w(),
                 q.x(), q.y(), q.z(), im.pose.t.x(), im.pose.t.y(), im.pose.t.z(), im.group + 1, im.name);
    }
    f.commit();
  }
  {
    AtomicFile f(folder / "points3D.txt");
    fmt::format_to(f.out(), "# POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] (image ids only; no 2D indices)\n");
    for (std::size_t p = 0; p < rec.points.size(); ++p) {
      const auto& pt = rec.points[p];
      fmt::format_to(f.out(), "{} {:.17g} {:.17g} {:.17g} {} {} {} {:.4f}\n", p + 1, pt.X.x(), pt.X.y(), pt.X.z(),
                 pt.colour(0), pt.colour(1), pt.colour(2), pt.error_px);
    }
    f.commit();
  }
}

}  // namespace strata
