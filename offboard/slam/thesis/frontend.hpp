// Front-end stage: features of every frame, S-NNMMT matching against the previous frame, RANSAC
// egomotion, and the pure visual-odometry chain T_odom_cam (product of frame-to-frame motions; the
// back-end maps it into the corrected world frame).
//
// Deterministic: the same frames give the same output (RANSAC seeds derive from the frame index).
// Not thread-safe: owned by the front-end thread (or the caller in sequential mode).
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "slam/core/types.hpp"
#include "slam/features/features.hpp"
#include "slam/matching/matching.hpp"
#include "slam/motion/motion.hpp"

namespace rgbdquad::slam {

struct FrontendOptions {
  FeatureOptions features;
  MatchOptions matching;
  RansacOptions ransac;
  /// Fewer RANSAC inliers than this and the frame-to-frame motion is not trusted (tracking lost,
  /// the motion is taken as zero). 10 three-point inliers over-determine a 6-DoF motion well.
  std::size_t min_inliers = 10;
  std::uint64_t seed = 20260101;  ///< base of every RANSAC seed (explicit, for reproducibility)
  bool is_valid(std::string* error) const;
};

/// Per-frame front-end result. Images and features are shared (read-only) with the back-end.
struct FrontendOutput {
  std::int64_t index = 0;
  double stamp_s = 0;
  RgbdFrame frame;
  std::shared_ptr<const FrameFeatures> features;
  Eigen::Isometry3d T_prev_cur = Eigen::Isometry3d::Identity();  ///< frame-to-frame egomotion
  Eigen::Isometry3d T_odom_cam = Eigen::Isometry3d::Identity();  ///< VO chain
  TrackingState state = TrackingState::kInitialising;
  std::size_t matches = 0;
  std::size_t inliers = 0;
  double rms_error_m = 0;
  double features_ms = 0, matching_ms = 0, ransac_ms = 0, total_ms = 0;
  double total_cpu_ms =
      0;  ///< CPU time of the calling thread (load-independent when OpenCV runs single-threaded)
};

class FrontEnd {
 public:
  static std::optional<FrontEnd> create(const FrontendOptions& options,
                                        const Intrinsics& intrinsics, std::string* error);
  /// Processes the next frame. Fails only on unusable images (message in `error`).
  std::optional<FrontendOutput> process(const RgbdFrame& frame, std::string* error);
  bool binary_descriptors() const { return extractor_.binary_descriptors(); }

 private:
  FrontEnd(FrontendOptions options, FeatureExtractor extractor);
  FrontendOptions options_;
  FeatureExtractor extractor_;
  std::shared_ptr<const FrameFeatures> prev_;
  Eigen::Isometry3d T_odom_prev_ = Eigen::Isometry3d::Identity();
};

/// Matches `cur` against `ref` and runs RANSAC on the lifted pairs. `matches_out` receives the
/// number of S-NNMMT pairs. Returns the estimate T_ref_cur (dst = ref, src = cur).
std::optional<MotionEstimate> estimate_between(const FrameFeatures& cur, const FrameFeatures& ref,
                                               const MatchOptions& match_options,
                                               const RansacOptions& ransac_options,
                                               std::uint64_t seed, std::size_t* matches_out,
                                               double* matching_ms = nullptr,
                                               double* ransac_ms = nullptr);

}  // namespace rgbdquad::slam
