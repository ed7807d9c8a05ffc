// Pose-graph optimisation with Ceres (Manifold API): nodes are keyframe poses T_world_cam
// (position p and unit quaternion q, Eigen storage order x y z w, EigenQuaternionManifold), edges
// are measured relative poses T_a_b (maps points of camera b into camera a) with a 6x6 diagonal
// square-root information from the RANSAC inlier statistics. Loop edges use a Cauchy robust loss so
// that one false loop closure cannot drag the whole map (the thesis lost fr2/pioneer_slam to one).
//
// Not thread-safe: owned by the back-end.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "slam/core/types.hpp"

namespace rgbdquad::slam {

struct PoseGraphEdge {
  std::int64_t from = 0;  ///< node a
  std::int64_t to = 0;    ///< node b
  Eigen::Isometry3d T_from_to = Eigen::Isometry3d::Identity();
  /// Square roots of the information diagonal: translation (1/m) then rotation (1/rad).
  Eigen::Matrix<double, 6, 1> sqrt_information = Eigen::Matrix<double, 6, 1>::Ones();
  bool loop = false;  ///< loop-closure edge: robust loss applies
};

struct PoseGraphOptions {
  /// Whitened residual (in sigmas) where the Cauchy loss starts to flatten: loop edges are added
  /// every frame, so a true one disagrees by a few sigmas at most; a false one by hundreds.
  double loop_cauchy_scale = 3.0;
  int max_iterations = 50;
  bool is_valid(std::string* error) const;
};

/// Square-root information for an edge from RANSAC statistics: n inliers with RMS alignment error
/// rms_m at a mean depth of depth_m. Translation sigma = max(rms, 5 mm)/sqrt(n); rotation sigma =
/// translation sigma / depth (a point error e at depth z tilts the view by about e/z). n is capped
/// at 25 (correlated errors), so sigma >= 1 mm.
Eigen::Matrix<double, 6, 1> edge_sqrt_information(std::size_t inliers, double rms_m,
                                                  double depth_m);

/// A gravity factor on one node (slam/core/types.hpp gravity_residual): the camera's roll and
/// pitch against the world's gravity direction. `observation.sigma_rad` is in the graph's units:
/// the caller divides the measurement's sigma by the rotation sigma its edges stand for.
struct PoseGraphGravity {
  std::int64_t node = 0;
  Eigen::Vector3d down_world = Eigen::Vector3d::UnitY();
  GravityObservation observation;
};

class PoseGraph {
 public:
  void add_node(std::int64_t id, const Eigen::Isometry3d& T_world_cam);
  /// Adds an edge between existing nodes; returns false (ignored) otherwise or when non-finite.
  bool add_edge(const PoseGraphEdge& edge);
  /// Adds a gravity factor on an existing node; returns false (ignored) otherwise.
  bool add_gravity(const PoseGraphGravity& gravity);
  /// Optimises with the first added node held fixed; returns the final cost, or a negative value
  /// when there is nothing to do or Ceres failed.
  double optimize(const PoseGraphOptions& options, std::string* report = nullptr);

  bool has_node(std::int64_t id) const { return nodes_.count(id) != 0; }
  Eigen::Isometry3d pose(std::int64_t id) const;
  void set_pose(std::int64_t id, const Eigen::Isometry3d& T_world_cam);
  const std::vector<PoseGraphEdge>& edges() const { return edges_; }
  std::vector<std::int64_t> node_ids() const;

  /// g2o text: VERTEX_SE3:QUAT id x y z qx qy qz qw / EDGE_SE3:QUAT a b x y z qx qy qz qw + upper
  /// triangle of the information matrix (translation first), as g2o and Ceres' example read it.
  std::string to_g2o() const;

 private:
  struct Node {
    Eigen::Vector3d p;
    Eigen::Quaterniond q;
  };
  std::map<std::int64_t, Node> nodes_;
  std::vector<PoseGraphEdge> edges_;
  std::vector<PoseGraphGravity> gravity_;
  std::int64_t first_ = -1;
};

}  // namespace rgbdquad::slam
