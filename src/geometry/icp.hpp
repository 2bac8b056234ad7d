#pragma once
// Rigid registration of a point cloud onto a surface (docs/range.md, "Registration"):
// robust point-to-plane ICP (Chen & Medioni 1992; linearised as Low 2004) with a
// Huber loss on the point-to-plane residual, trimmed correspondences and a
// correspondence gate that shrinks with the fit, preceded by a coarse search over
// the rotation about the vertical for frames whose z axis is already up (a levelled
// tripod scanner). Eigen only; nearest neighbours from a voxel-hash grid.
#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <map>
#include <unordered_map>
#include <utility>
#include <vector>

namespace strata {

// A surface sampled as points with unit normals (metres, one frame).
struct OrientedPoints {
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector3d> normals;
};

// One point per occupied cube of `voxel_m` (the mean of the points in it), in a
// deterministic order: the cloud thinned to an even density.
std::vector<Eigen::Vector3d> voxel_subsample(const std::vector<Eigen::Vector3d>& points, double voxel_m);

// The same for a cloud that grows (a model built frame by frame): the running mean
// of the points added to each cube so far.
class VoxelMeans {
 public:
  explicit VoxelMeans(double voxel_m);
  void add(const Eigen::Vector3d& p);
  std::vector<Eigen::Vector3d> points() const;  // one a cube, in a deterministic order

 private:
  double voxel_;
  std::map<std::int64_t, std::pair<Eigen::Vector3d, int>> cells_;
};

// Normals by principal components of the neighbours within `radius_m` (at least 5
// of them; points with fewer are dropped), turned to face +z (surfaces seen from
// above: floors, trench sides).
OrientedPoints estimate_normals(const std::vector<Eigen::Vector3d>& points, double radius_m);

// The growing model of frame-to-model tracking: the running mean of each cube of
// `voxel_m` (as VoxelMeans) with its normal from the means within `normal_radius_m`
// (as estimate_normals), kept up to date as frames are added: a frame's points change
// the means of the cubes they fall in, and only the cubes within the radius of one of
// those get their normal estimated again (KinectFusion's model is incremental for the
// same reason: the cost of a frame should not grow with the whole model).
class GrowingModel {
 public:
  GrowingModel(double voxel_m, double normal_radius_m);
  void add(const std::vector<Eigen::Vector3d>& points);  // one frame's points, the model's frame
  // The cubes with a normal (at least 5 neighbours), in the cubes' key order: the same
  // points and normals as estimate_normals(VoxelMeans::points(), radius), up to rounding.
  const OrientedPoints& oriented() const { return oriented_; }
  std::size_t cubes() const { return cubes_.size(); }
  std::size_t normals_estimated() const { return normals_estimated_; }  // over every add(), for the tests

 private:
  struct Cube {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    int count = 0;
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    bool has_normal = false;
  };
  double voxel_, radius_;
  int bin_cubes_;  // cubes a bin side: a bin is at least the radius wide
  std::map<std::int64_t, Cube> cubes_;
  std::unordered_map<std::int64_t, std::vector<Cube*>> bins_;  // bin key -> its cubes (map nodes stay put)
  OrientedPoints oriented_;
  std::size_t normals_estimated_ = 0;
};

struct IcpOptions {
  int max_iterations = 100;
  double max_correspondence_m = 0.10;  // metres: initial gate on the point-to-point distance
  double min_correspondence_m = 0.01;  // metres: the gate never shrinks below this
  double gate_rms_factor = 3.0;        // the gate follows this many inlier RMS residuals
  double huber_m = 0.005;              // metres: Huber threshold on the point-to-plane residual
  double trim_share = 0.10;            // share of the gated pairs with the largest residuals dropped
  double converged_step_m = 1e-5;      // metres: stop when an update moves the points less than this (10 um)
  // Degeneracy (after Gelfand et al. 2003, "Geometrically stable sampling for ICP"):
  // for each eigenvector v of the normal equations (rotation scaled by the cloud's
  // radius), the share of inliers whose residual responds to it, |J_i . v| >= 0.3
  // with a rotation taken at the point's own lever arm (a surface turned 17 degrees
  // or more towards that motion). Below this share a
  // direction rests on the noise of the normals, not on the shape: a plane's in-plane
  // shift and its rotation about its normal.
  double min_support_share = 0.01;
  void validate() const;  // throws InputError naming the field
};

struct IcpSummary {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // source frame -> target frame
  int iterations = 0;
  bool converged = false;
  double rms_m = 0;          // RMS point-to-plane residual of the inliers, metres
  double inlier_share = 0;   // inliers over the source points
  int inliers = 0;
  // Pose covariance from the normal equations, sigma^2 (J^T W J)^-1, rotation
  // (radians) then translation (metres), the rotation about the inliers' centroid.
  // Residuals of neighbouring points are correlated, so this is a lower bound.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  double sigma_translation_m = 0;  // sqrt of the largest eigenvalue of the translation block
  double sigma_rotation_rad = 0;   // same for the rotation block
  double eigen_ratio = 0;          // smallest over largest eigenvalue of the scaled normal equations
  double support_share = 0;        // the least supported direction, see IcpOptions::min_support_share
  bool degenerate = false;         // support_share < min_support_share: no covariance
};

// Refines `initial` (source -> target) so the source points lie on the target
// surface. `target` must have normals.
IcpSummary register_point_to_plane(const std::vector<Eigen::Vector3d>& source, const OrientedPoints& target,
                                   const Eigen::Isometry3d& initial, const IcpOptions& options);

struct CoarseOptions {
  double yaw_step_rad = 0.1745329;   // 10 degrees between the tried rotations about z
  double voxel_m = 0.05;             // metres: both clouds thinned to this for the search
  int iterations = 12;               // short ICP from each yaw
  double gate_m = 0.30;              // metres: its initial correspondence gate
  double score_gate_m = 0.02;        // metres: a yaw is scored by the share of points this near the
                                     // surface (point-to-plane, nearest target point within voxel_m)
  int max_source_points = 1500;      // the source is thinned further, evenly, to this many
};

struct CoarseResult {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // best start, source -> target
  double yaw_rad = 0;   // the tried yaw that led to it
  double score = 0;     // share of source points within score_gate_m after the short ICP
};

// Global start for a source whose z axis is (nearly) the target's: for each yaw,
// the source turned about its centroid, its centroid put on the target's (plan and
// median height), a short ICP; the best by score.
CoarseResult coarse_yaw_search(const std::vector<Eigen::Vector3d>& source, const std::vector<Eigen::Vector3d>& target,
                               const CoarseOptions& options = {});

// The plane most points lie on (for a cloud of the ground, the ground: a hand-held
// sequence's frame is not levelled; the normal of this plane is its up direction, up
// to sign). RANSAC (Fischler & Bolles 1981) over planes through three points,
// deterministic (a fixed seed), refined by principal components of its inliers.
struct PlaneFit {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit; its sign is arbitrary
  Eigen::Vector3d point = Eigen::Vector3d::Zero();    // the inliers' centroid, on the plane
  double inlier_share = 0;                            // points within tolerance_m of it
};
PlaneFit dominant_plane(const std::vector<Eigen::Vector3d>& points, double tolerance_m, int hypotheses = 500);

}  // namespace strata
