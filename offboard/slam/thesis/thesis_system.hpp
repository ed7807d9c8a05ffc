// The thesis's SLAM systems (VO, VO+LLC, VO+GLC; `slam-study` reproduces them): a front-end
// (features, S-NNMMT matching, RANSAC egomotion) and a back-end (keyframes, loop closure, pose
// graph), each on its own thread, joined by one-slot hand-overs.
//
// Pacing (PipelineMode; kLive behaves as kSequential):
//  - kSequential: both run on the caller's thread;
//  - kWait: every frame goes through both, in order; the two threads overlap across consecutive
//    frames and the result equals kSequential's;
//  - kRealtime: submit() never blocks: a frame arriving while the front-end still holds an
//    unprocessed one replaces it (frontend_dropped); the back-end takes the latest front-end
//    output and skips the rest (backend_skipped). Poses of skipped frames are the front-end's
//    odometry mapped through the latest back-end correction.
//
// Thread safety: submit()/finish() from one producer thread; results from any thread.
#pragma once

#include <atomic>
#include <memory>
#include <mutex>
#include <thread>

#include "slam/core/stage_queue.hpp"
#include "slam/pipeline/frame_records.hpp"
#include "slam/pipeline/pipeline_options.hpp"
#include "slam/pipeline/slam_system.hpp"
#include "slam/thesis/backend.hpp"
#include "slam/thesis/frontend.hpp"

namespace rgbdquad::slam {

class ThesisSystem : public SlamSystem {
 public:
  /// `options.mode` kLive is taken as kSequential; `records` outlives the system.
  static std::unique_ptr<ThesisSystem> create(const PipelineOptions& options,
                                              const Intrinsics& intrinsics, FrameRecords* records,
                                              std::string* error);
  ~ThesisSystem() override;

  void submit(RgbdFrame frame) override;
  void finish() override;
  PipelineSummary summary() const override;
  std::vector<std::pair<double, Eigen::Isometry3d>> final_trajectory() const override;
  /// Valid after finish() (the back-end thread owns it while running).
  const BackEnd& backend() const { return backend_; }

 private:
  ThesisSystem(PipelineMode mode, FrontEnd frontend, BackEnd backend, FrameRecords* records);
  void frontend_loop();
  void backend_loop();
  void run_frontend(const RgbdFrame& frame);
  void run_backend(const FrontendOutput& out);

  const PipelineMode mode_;
  FrontEnd frontend_;
  BackEnd backend_;
  FrameRecords* records_;
  StageQueue<RgbdFrame> input_{1};
  StageQueue<FrontendOutput> handover_{1};
  std::atomic<bool> finished_{false};
  std::atomic<bool> joined_{false};  // set once both threads are joined
  mutable std::mutex mutex_;         // guards the fields below
  // Latest back-end correction C = T_world_cam * T_odom_cam^-1 (used for skipped frames).
  Eigen::Isometry3d correction_ = Eigen::Isometry3d::Identity();
  std::uint64_t loop_corrections_ = 0;  // loop closures folded into correction_
  std::size_t frontend_dropped_ = 0, backend_skipped_ = 0;
  std::thread frontend_thread_;
  std::thread backend_thread_;
};

}  // namespace rgbdquad::slam
