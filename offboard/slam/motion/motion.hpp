// Motion stage: rigid alignment of 3D point pairs (Umeyama/Kabsch without scale, optionally
// weighted) inside RANSAC.
//
// Convention: pairs are (src_i, dst_i); the estimate T_dst_src maps src points onto dst points:
// dst ~= T_dst_src * src. For egomotion, src = current frame points and dst = reference frame
// points, so T_dst_src = T_ref_cur.
//
// RANSAC (thesis Sec. 3.4, Table 4.4): inlier threshold 3 cm, accept when >= 60 % of the pairs are
// inliers. Two sampling schemes:
//  - kThesis: Umeyama on 4 pairs taken in order of descriptor distance (best first), next 4 on a
//    retry, up to 10 attempts, keeping the best;
//  - kRandom (default): random minimal 3-pair samples from an explicitly seeded generator, with the
//    iteration count adapted to the inlier ratio seen so far.
// Both end with a least-squares refit on all inliers, repeated until the inlier set is stable, and
// an optional depth-weighted refit (Kinect depth noise grows with z^2).
//
// Stateless functions; thread-safe.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace rgbdquad::slam {

/// Least-squares rigid transform (no scale) minimising sum w_i |T*src_i - dst_i|^2. Needs >= 3
/// non-collinear pairs and positive weights (empty weights = all 1). Returns nullopt when
/// degenerate.
std::optional<Eigen::Isometry3d> umeyama_rigid(const std::vector<Eigen::Vector3d>& src,
                                               const std::vector<Eigen::Vector3d>& dst,
                                               const std::vector<double>& weights = {});

enum class RansacSampling { kThesis, kRandom };

struct RansacOptions {
  double inlier_threshold_m = 0.03;   ///< thesis Table 4.4
  double accept_inlier_ratio = 0.60;  ///< thesis Table 4.4
  RansacSampling sampling = RansacSampling::kRandom;
  int thesis_sample_size = 4;         ///< thesis: 4 pairs closest in descriptor space
  int thesis_max_attempts = 10;       ///< thesis: up to 10 retries
  int max_iterations = 300;           ///< cap on random samples (kRandom)
  int min_iterations = 20;            ///< random samples drawn even when the first looks perfect
  double confidence = 0.995;          ///< adaptive stop: P(at least one all-inlier sample)
  int refit_rounds = 4;               ///< LS refit / re-classify rounds after the best sample
  bool depth_weighted_refine = true;  ///< final refit weighted by 1/z^2 (Kinect noise model)
  std::size_t min_pairs = 6;          ///< fewer pairs: no estimate
  /// Optional final refinement: Gauss-Newton on the symmetric reprojection error of the inliers
  /// (pixels are precise, Kinect depth is not). Needs the pinhole intrinsics; off when fx_px = 0.
  struct Pinhole {
    double fx_px = 0, fy_px = 0, cx_px = 0, cy_px = 0;
  } reprojection_camera;
  int reprojection_iterations = 5;
  double reprojection_huber_px = 2.0;  ///< Huber threshold: ~2x the keypoint localisation noise
  bool is_valid(std::string* error) const;
};

/// One residual of refine_reprojection with its analytic Jacobian, exposed so tests can check the
/// Jacobian against numeric derivatives. `jacobian` is d(residual)/d(delta) for the left increment
/// T' = exp(delta) * T, delta = (translation m, rotation vector rad), the update the solver
/// applies.
struct ReprojectionTerm {
  Eigen::Vector2d residual_px = Eigen::Vector2d::Zero();
  Eigen::Matrix<double, 2, 6> jacobian = Eigen::Matrix<double, 2, 6>::Zero();
  bool valid = false;  ///< false when the transformed point is closer than 0.1 m (no information)
};

/// Forward term: pi(T src) against pi(dst).
ReprojectionTerm forward_reprojection_term(const Eigen::Isometry3d& T_dst_src,
                                           const Eigen::Vector3d& src, const Eigen::Vector3d& dst,
                                           const RansacOptions::Pinhole& camera);
/// Backward term: pi(T^-1 dst) against pi(src).
ReprojectionTerm backward_reprojection_term(const Eigen::Isometry3d& T_dst_src,
                                            const Eigen::Vector3d& src, const Eigen::Vector3d& dst,
                                            const RansacOptions::Pinhole& camera);

/// Refines T_dst_src by minimising sum_i rho(|pi(T src_i) - pi(dst_i)|^2) +
/// rho(|pi(T^-1 dst_i) - pi(src_i)|^2) over the given pairs (Gauss-Newton, Huber weights).
/// Returns the input unchanged when the problem is degenerate or the cost does not decrease.
Eigen::Isometry3d refine_reprojection(const Eigen::Isometry3d& T_dst_src,
                                      const std::vector<Eigen::Vector3d>& src,
                                      const std::vector<Eigen::Vector3d>& dst,
                                      const std::vector<int>& pairs,
                                      const RansacOptions::Pinhole& camera, int iterations,
                                      double huber_px);

struct MotionEstimate {
  Eigen::Isometry3d T_dst_src = Eigen::Isometry3d::Identity();
  std::vector<int> inliers;   ///< indices into the pair list
  double inlier_ratio = 0.0;  ///< inliers / pairs
  double rms_error_m = 0.0;   ///< RMS alignment error over inliers
  bool accepted = false;      ///< inlier_ratio >= accept_inlier_ratio
  int iterations = 0;         ///< samples evaluated
};

/// RANSAC rigid alignment. `order` (optional) lists pair indices best-first by descriptor distance,
/// used by kThesis sampling (identity order when empty). `seed` makes kRandom reproducible.
/// Returns nullopt (with a reason) when there are too few pairs or every sample is degenerate.
std::optional<MotionEstimate> estimate_motion_ransac(const std::vector<Eigen::Vector3d>& src,
                                                     const std::vector<Eigen::Vector3d>& dst,
                                                     const std::vector<int>& order,
                                                     const RansacOptions& options,
                                                     std::uint64_t seed, std::string* why);

}  // namespace rgbdquad::slam
