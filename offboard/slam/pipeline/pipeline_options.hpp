// The options that build one SLAM system (PipelineOptions) and how its threads are paced
// (PipelineMode).
#pragma once

#include <string>

#include "slam/core/thread_priority.hpp"
#include "slam/loopclosing/loop_closer.hpp"
#include "slam/mapping/local_mapper.hpp"
#include "slam/thesis/backend.hpp"
#include "slam/thesis/frontend.hpp"
#include "slam/tracking/tracker.hpp"

namespace rgbdquad::slam {

/// kLive: submit() tracks on the caller's thread (the frame's pose is final when it returns) while
/// the local map is refined on the mapping thread - for servers that answer every frame
/// (slam-server). For the thesis back-ends kLive behaves as kSequential.
enum class PipelineMode { kSequential, kWait, kRealtime, kLive };
bool parse_pipeline_mode(const std::string& name, PipelineMode* out, std::string* error);
const char* to_string(PipelineMode m);

struct PipelineOptions {
  FrontendOptions frontend;
  BackendOptions backend;
  PipelineMode mode = PipelineMode::kWait;
  /// Refine every RANSAC estimate on the reprojection error (RansacOptions::reprojection_camera is
  /// filled from the intrinsics when true).
  bool reprojection_refine = true;
  TrackerOptions tracker;  ///< BackendKind::kLocalMap only
  /// BackendKind::kLocalMap: its ORB extractor's FeatureOptions::orb_spread_oversample (the
  /// thesis systems keep `frontend.features`, cv::ORB's own choice as in thesis Table 4.3). Off
  /// (0) by default: spreading from twice the corners (2) lowers the wait-mode ATE of the real TUM
  /// excerpts, but with it the 10-minute HIL flight on a loaded 2-core machine lost its margin -
  /// the serving thread's CPU rose from 10.8 to 14.4 ms a frame, pose latency p95 doubled, SLAM
  /// answered 82 % of the frames instead of 96 % and the first minute's error missed 20 mm (results
  /// page, docs/slam.md). 2 (ORB-SLAM2-like: at level 0 cv::ORB keeps ~770 corners over ~330 cells
  /// of 30 px, 2.3 a cell) is the value to try where the CPU allows.
  int local_map_orb_spread_oversample = 0;
  /// BackendKind::kLocalMap: sigma of the depth (disparity) residual (see DepthNoiseModel).
  DepthNoiseModel depth_noise = DepthNoiseModel::kKeypointSigma;
  /// BackendKind::kLocalMap: the map lock inherits the priority of a waiting real-time tracker
  /// (SharedMap / MapMutex); false only to measure what it changes.
  bool map_lock_priority_inheritance = true;
  /// kRealtime: scheduling of the tracking thread (slam-server and quad-control raise theirs; off
  /// leaves it as created). Lets `slam-eval --mode realtime` measure the real-time path.
  ThreadPolicy tracking_thread_policy = ThreadPolicy::kOff;
  /// kRealtime/kLive, local map: when tracking runs under a real-time policy (asked above, or
  /// inherited from a real-time creator: slam-server), the mapping thread runs SCHED_RR at this
  /// priority, below the camera-to-command path (10, quad-control's firmware link 12) and above
  /// all normal work; 0 keeps it on the normal policy at a nice below its creator. Why not nice:
  /// Linux shares the CPU between processes (autogroups, systemd cgroups) before it looks at a
  /// thread's nice, so beside a CPU load in another session the mapper got 1/4.85 of its wall time
  /// (slam-eval realtime on fr1_xyz, stress-ng --cpu 2 under setsid) and in a fresh-clone demo
  /// 1/13, until tracking ran out of keyframes and was lost. Its cost is bounded per keyframe (the
  /// local window) and it yields its backlog (LocalMapper's catch-up), so it cannot hold a core.
  int mapping_rt_priority = 5;
  LocalMapperOptions mapper;  ///< BackendKind::kLocalMap only
  /// BackendKind::kLocalMap: loop closing on its own thread (binary descriptors only: the
  /// vocabulary is ORB's; with SIFT/SURF it stays off and PipelineSummary says so). On by default:
  /// with ORB-SLAM2's temporal consistency and the odometry-consistency gate
  /// (loop/loop_consistency.hpp) a replayed HIL flight that had accepted two wrong loops (ATE
  /// 0.398 m) accepts its one true loop only (ATE 0.0069 m); no loop is accepted on the TUM
  /// excerpts.
  bool loop_closing = true;
  /// kRealtime/kLive: ORB-SLAM2's c1b/c1c gate - while the mapper is busy only weak tracking makes
  /// a keyframe. Off by default: with it on, the HIL 10-minute flight on an idle machine drifted
  /// (ATE 0.109 m, loop closing off) or accepted a wrong loop correction (0.73 m, loop closing on);
  /// with it off the same build flew 4 minutes at SLAM error 6-8 mm (docs/hil.md). Our mapper runs
  /// niced below a real-time tracker, so "busy" is most of the time in flight, and the gate then
  /// withholds the keyframes the map needs; ORB-SLAM2's mapper is not starved that way.
  bool keyframe_gate_mapper_busy = false;
  LoopCloserOptions
      loop;  ///< matching, RANSAC and projection settings are filled in from the tracker's
  /// BackendKind::kLocalMap: map checkpoints. When set, the map (with its count of loop
  /// corrections) is written here - through a temporary file renamed into place - once it has
  /// changed (a keyframe mapped, keyframes culled, a loop correction) and `checkpoint_period_s` of
  /// data time have passed since the last write, whether or not another keyframe comes (at once
  /// for the first checkpoint and after a loop correction), and once more by finish()
  /// (MapCheckpointer). A service restarted after a crash loads it and continues in the same map
  /// and world frame (slam-server --checkpoint-dir). The map is copied under the map lock (the
  /// tracker waits for the copy only) and written on its own thread, never the tracking thread.
  std::string checkpoint_path;
  /// 1 s: a restarted service can relocalise only where the checkpoint has keyframes, and the
  /// views of the last seconds are the ones the craft still sees. With 5 s, a HIL restart in the
  /// hover found only the take-off's keyframes (the climb's were newer than the checkpoint) and
  /// stayed lost for 33 frames, past quad-control's 2 s lost-hold: it landed. A map that does not
  /// change (steady hover, revisits) is not rewritten; what a write costs is in docs/slam.md.
  double checkpoint_period_s = 1.0;
  /// BackendKind::kLocalMap: records the order in which tracking, mapping and loop closing take
  /// the map and the timing-dependent answers they are given (slam/core/lock_schedule.hpp), so
  /// that a real-time run can be replayed exactly from the same frames.
  std::string lock_schedule_record_path;
  /// Replays such a record: each thread takes the map only in its recorded turn. With the same
  /// frames, binary and options the poses are the recorded run's bit for bit; a replay that leaves
  /// the record runs free from there (PipelineSummary::lock_schedule says where).
  std::string lock_schedule_replay_path;
  /// `--depthless-observations`: "off", "on" (tracking fits them) or "map" (keyframes keep them
  /// and the mapper triangulates points from them); the tracker and mapper fields together.
  void set_depthless_observations(const std::string& mode);
  /// The mode the tracker and mapper fields say (the default's name for --help).
  std::string depthless_observations() const;
  bool is_valid(std::string* error) const;
};

}  // namespace rgbdquad::slam
