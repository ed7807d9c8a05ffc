// What the pipeline facade asks of a SLAM system: frames in, records and a trajectory out. Two
// systems implement it: LocalMapSystem (the flying system: tracking, local mapping and loop
// closing, each on its own thread) and ThesisSystem (the thesis's VO / VO+LLC / VO+GLC front-end
// and back-end).
//
// Thread safety: submit() and finish() from one producer thread; the rest from any thread.
#pragma once

#include <Eigen/Geometry>
#include <utility>
#include <vector>

#include "slam/core/types.hpp"
#include "slam/pipeline/frame_record.hpp"

namespace rgbdquad::slam {

class SlamSystem {
 public:
  virtual ~SlamSystem() = default;
  /// Hands over the next frame, paced as the system's mode says (PipelineMode).
  virtual void submit(RgbdFrame frame) = 0;
  /// Drains every stage and joins the threads. Called once.
  virtual void finish() = 0;
  /// The system's counters (the facade adds frames_submitted and frames_failed).
  virtual PipelineSummary summary() const = 0;
  /// After finish(): each held record's pose, re-anchored to its keyframe's optimised pose.
  virtual std::vector<std::pair<double, Eigen::Isometry3d>> final_trajectory() const = 0;
};

}  // namespace rgbdquad::slam
