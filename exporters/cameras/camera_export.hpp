#pragma once
// exporter.cameras.csv and exporter.cameras.colmap.
#include "sfm/reconstruction.hpp"

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

// COLMAP text model (cameras.txt with the RADIAL-like OPENCV model, images.txt,
// points3D.txt) in the site frame. COLMAP puts pixel (0,0) at the corner of the
// top-left pixel, so principal points are shifted by +0.5.
void write_colmap_model(const Reconstruction& rec, const std::filesystem::path& folder);

}  // namespace strata
