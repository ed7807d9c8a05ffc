// What a SLAM run reports: one record per frame and a summary of the run. Plain values, shared by
// both SLAM systems (the local-map system and the thesis systems) and by the tools that report on
// them.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "slam/tracking/tracker.hpp"

namespace rgbdquad::slam {

/// Everything known about one frame once the pipeline is finished.
struct FrameRecord {
  std::int64_t index = 0;
  double stamp_s = 0;
  bool ok = false;  ///< false: the front-end rejected the frame (see error)
  std::string error;
  TrackingState state = TrackingState::kInitialising;
  bool backend_processed = false;
  bool keyframe = false;
  bool llc_applied = false;
  bool loop_closed = false;
  bool relocalised =
      false;  ///< local-map system: the pose came from the keyframe database (TrackResult)
  bool cross_checked = false;   ///< local-map system: a weak fit was cross-checked (TrackResult)
  bool new_segment = false;     ///< local-map system: the frame started a map segment (TrackResult)
  bool segment_merged = false;  ///< local-map system: the segment joined the map (TrackResult)
  /// Local-map system: a fit only the motion bound refused was confirmed by a registration to the
  /// reference keyframe and kept (TrackResult).
  bool off_path_confirmed = false;
  /// Local-map system: a pose disagreeing with the frame's attitude was refused (TrackResult).
  bool attitude_refused = false;
  bool gravity_prior = false;  ///< local-map system: the pose fit had a gravity prior
  /// local-map system: the rolling-shutter refit's angular velocity (camera frame, rad/s)
  std::optional<std::array<double, 3>> rolling_shutter_rate_rad_per_s;
  double cross_check_shift_m = -1, cross_check_shift_deg = -1;  ///< (TrackResult)
  bool prediction_stale =
      false;  ///< local-map system: the gap exceeded the tracker's max_predicted_gap_s
  bool attitude_predicted = false;  ///< local-map system: rotation predicted from the IMU attitude
  double prediction_deviation_m = -1,
         prediction_deviation_bound_m = -1;  ///< local-map system (TrackResult)
  std::int64_t reference_keyframe = -1;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();  ///< as estimated online
  Eigen::Isometry3d T_prev_cur = Eigen::Isometry3d::Identity();   ///< front-end egomotion
  Eigen::Isometry3d T_kf_cam = Eigen::Isometry3d::Identity();
  std::size_t features = 0, matches = 0, inliers = 0;
  std::size_t depthless_inliers = 0;  ///< local-map system (TrackResult)
  /// Local-map system: matching_ms = local map + projection search with its pose optimisations,
  /// ransac_ms = relocalisation (TrackResult).
  double features_ms = 0, matching_ms = 0, ransac_ms = 0, frontend_ms = 0;
  double keyframe_ms = 0, llc_ms = 0, glc_ms = 0, posegraph_ms = 0, backend_ms = 0;
  double frontend_cpu_ms = 0, backend_cpu_ms = 0;
  std::size_t map_keyframes = 0, map_points = 0;  ///< local-map system: map size after this frame
  /// Local-map system: the keyframe rule's verdict and inputs (TrackResult).
  KeyframeReason keyframe_wanted = KeyframeReason::kNone;
  int ref_tracked = 0, near_tracked = 0, near_untracked = 0;
  double near_redundant = -1;
  double map_lock_wait_ms =
      0;  ///< local-map system: the tracker's wait for the map lock (TrackResult)
  /// Map corrections T_world_cam is expressed after: loop corrections of the local map
  /// (TrackResult), or loop closures the VO back-end had applied when this pose was given. A change
  /// from one frame to the next declares a jump of the world frame (PoseUpdate.map_correction_count
  /// on the wire).
  std::uint64_t map_corrections = 0;
};

struct PipelineSummary {
  std::size_t frames_submitted = 0;
  std::size_t frontend_dropped =
      0;  ///< real-time mode: frames replaced before the front-end took them
  std::size_t backend_skipped = 0;  ///< real-time mode: front-end outputs the back-end never saw
  std::size_t frames_failed = 0;
  std::size_t keyframes = 0;
  std::size_t loop_closures = 0;
  std::size_t optimisations = 0;
  // Local-map system only:
  std::size_t map_points = 0;
  std::size_t keyframes_culled = 0;
  std::size_t relocalisations = 0;  ///< frames whose pose came from the keyframe database
                                    ///< after a loss or a stale prediction
  /// Weak fits cross-checked against the reference keyframe, and those whose pose it replaced.
  std::size_t cross_checks = 0, cross_check_replacements = 0;
  std::size_t frames_lost = 0;
  /// Frames that could be neither tracked nor relocalised and started a new map segment
  /// (TrackerOptions::restart_when_lost).
  std::size_t segments_started = 0;
  /// Segments moved onto the map before them when their place was recognised.
  std::size_t segments_merged = 0;
  /// Fits only the motion bound refused, kept because the reference keyframe confirmed them
  /// (TrackerOptions::confirm_off_path).
  std::size_t off_path_confirmed = 0;
  /// Relocalisations or segment merges refused for disagreeing with the frame's attitude
  /// (TrackerOptions::max_attitude_disagreement_deg).
  std::size_t attitude_refusals = 0;
  /// Frames whose pose fit had a gravity prior (TrackerOptions::gravity).
  std::size_t gravity_frames = 0;
  bool loop_closing_active =
      false;  ///< the loop closer ran (option on and a vocabulary for the detector)
  std::size_t loop_detections = 0;  ///< keyframes with database candidates passed to verification
  std::string
      tracking_thread;  ///< the tracking thread's scheduling, when PipelineOptions asked for one
  std::string mapping_thread;  ///< the local-mapping thread's scheduling (realtime/live modes)
  std::size_t mapper_caught_up = 0;  ///< keyframes whose fusion/BA was left to a newer keyframe
  std::size_t mapper_ba_interrupted = 0;  ///< local BAs stopped early by a waiting keyframe
  /// Map checkpoints (PipelineOptions::checkpoint_path): written, the slowest copy + write (ms),
  /// and the last failure ("" when none).
  std::size_t checkpoints_written = 0;
  double checkpoint_max_ms = 0;
  std::string checkpoint_error;
  /// The lock schedule's account (LockSchedule::describe); empty: none recorded or replayed.
  std::string lock_schedule;
};

}  // namespace rgbdquad::slam
