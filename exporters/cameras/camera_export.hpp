#pragma once
// exporter.cameras.csv and exporter.cameras.colmap.
#include "geometry/reconstruction.hpp"

#include <Eigen/Core>

#include <filesystem>

namespace strata {

// One row per registered photo, header exactly
// image,fx,fy,ppx,ppy,k1,k2,r11,r12,r13,r21,r22,r23,r31,r32,r33,X,Y,Z
// intrinsics in pixels ((0,0) = centre of the top-left pixel), world-to-camera
// rotation, camera centre in site CRS coordinates (site frame + origin), printed
// with 17 significant digits so nothing is lost.
void write_cameras_csv(const Reconstruction& rec, const Eigen::Vector3d& site_origin,
                       const std::filesystem::path& out);

// The same with every lens model's terms (exporter.cameras.csv-lens), header exactly
// image,model,fx,fy,ppx,ppy,k1,k2,k3,k4,p1,p2,r11,...,r33,X,Y,Z
// model: radial | brown | fisheye (geometry/camera.hpp); terms a model does not have
// are 0. The plain csv above keeps its documented header, so it cannot carry them.
void write_cameras_lens_csv(const Reconstruction& rec, const Eigen::Vector3d& site_origin,
                            const std::filesystem::path& out);

// COLMAP text model (cameras.txt: OPENCV for radial, FULL_OPENCV for brown,
// OPENCV_FISHEYE for fisheye; images.txt,
// points3D.txt) in the site frame. COLMAP puts pixel (0,0) at the corner of the
// top-left pixel, so principal points are shifted by +0.5.
void write_colmap_model(const Reconstruction& rec, const std::filesystem::path& folder);

}  // namespace strata
