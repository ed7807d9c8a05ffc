// quad-control's link to SLAM: slam-server over protocol/'s SLAM link (SlamServerClient,
// slam_server_client.hpp), or the SLAM engine's local-map system (offboard/slam, Pipeline in live
// mode: tracking on the link's thread, mapping on its own) in-process (InProcessSlam), behind one
// interface.
// Semantics of both (thesis): the newest frame is handed over; a frame arriving while SLAM is busy
// is dropped (counted). Results are delivered through the callback on the SLAM thread.
#pragma once

#include <Eigen/Geometry>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "app/frame_mailbox.hpp"
#include "app/frame_source.hpp"
#include "slam/core/thread_priority.hpp"
#include "slam/pipeline/pipeline.hpp"

namespace rgbdquad::quadcontrol {

struct SlamResult {
  std::int64_t frame_sequence = 0;
  std::int64_t capture_us = 0;
  bool tracking = false;
  std::string state;  ///< "initialising", "tracking", "lost"
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();  ///< world = first camera frame
  std::size_t inliers = 0;
  double latency_ms = 0.0;  ///< hand-over to result
  /// +1 each time the link starts a new SLAM map: poses of a new map are in a new world frame (its
  /// first camera). A reconnect that resumes the map keeps the number.
  std::uint64_t session = 0;
  /// SLAM's map-correction counter (PoseUpdate.map_correction_count): +1 each time SLAM
  /// corrected its world-frame trajectory discontinuously (a loop correction that moved the map).
  std::uint32_t map_correction_count = 0;
};

/// The link's own health, for the dashboard and the demo's verdict (thread-safe copy).
struct SlamLinkStatus {
  std::uint64_t sessions_started = 0;  ///< new maps (1 in a healthy flight; more = SLAM map resets)
  std::uint64_t resumes = 0;           ///< reconnects that continued the same map and world frame
  std::uint64_t disconnects = 0;       ///< connections that broke (each logged with its cause)
  std::string session_id;              ///< hex; "" for the in-process link
  std::string last_disconnect;         ///< cause of the last one
};

class SlamLink {
 public:
  using Callback = std::function<void(const SlamResult&, const CameraFrame&)>;
  virtual ~SlamLink() = default;
  /// Hands over a frame; false when SLAM is busy (the frame is dropped).
  virtual bool submit(const CameraFrame& frame) = 0;
  virtual SlamStats stats() const = 0;
  virtual std::string name() const = 0;
  virtual SlamLinkStatus link_status() const { return SlamLinkStatus{1, 0, 0, "", ""}; }
};

class InProcessSlam : public SlamLink {
 public:
  /// `priority`: the tracking thread's scheduling (the real-time path).
  static std::unique_ptr<InProcessSlam> create(const slam::Intrinsics& intrinsics,
                                               Callback callback,
                                               const slam::ThreadPriorityOptions& priority,
                                               std::string* error);
  ~InProcessSlam() override;
  bool submit(const CameraFrame& frame) override;
  SlamStats stats() const override;
  std::string name() const override { return "in-process local-map SLAM (offboard/slam)"; }

 private:
  InProcessSlam(std::unique_ptr<slam::Pipeline> pipeline, Callback callback,
                slam::ThreadPriorityOptions priority);
  void run();

  std::unique_ptr<slam::Pipeline> pipeline_;
  Callback callback_;
  FrameMailbox mailbox_;
  slam::AccelGate accel_gate_;  ///< used only by the tracking thread (run())
  std::thread thread_;
};

}  // namespace rgbdquad::quadcontrol
