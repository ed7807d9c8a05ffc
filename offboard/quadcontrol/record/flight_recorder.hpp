// quad-control's MCAP flight recorder: what the ground station saw and did, in the
// container ROS 2 bags and Foxglove use, readable by any MCAP tool (docs/recording.md lists the
// channels, units and frames).
//
// Images: every frame's RGB and depth are stored as the camera link carried them (JPEG; RVL or
// zstd-delta depth), shared with the receiver, so recording every frame costs no image encoding;
// only frames that came decoded (the dataset replay, a raw stream) are encoded here (JPEG, RVL).
// Off the camera-to-command path: the hooks (frame, pose, command, reply, event, map) only copy a
// small value (images are shared buffers) into a queue bounded by count and by bytes, under a
// priority-inheritance mutex (the producers are real-time threads, the writer is not), and return;
// one writer thread encodes (JSON, base64), writes and flushes. A full queue drops the event and
// counts it; nothing ever waits for the disk. Per-frame memory and CPU do not grow with the
// flight's length (the queue is bounded, chunks are closed at a size and a period, the MCAP chunk
// index grows by ~100 B per chunk). Crash safety: the writer closes its chunk about once a second
// (flush_period_ms), so a quad-control killed by SIGKILL leaves a file a streaming reader reads up
// to its last second. Budget: a file is rotated at max_file_mb; when this run's files exceed
// max_total_mb the oldest of them is deleted (a flight recorder keeps the end of the flight). A
// write error (disk full, file size limit) stops recording with one logged line; the flight goes
// on. Thread safety: every public method may be called from any thread.
#pragma once

#include <Eigen/Geometry>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include "core/flight_controller.hpp"
#include "core/stick_mapping.hpp"
#include "link/control_codec.hpp"
#include "map/floor_map.hpp"
#include "record/encoded_image.hpp"
#include "slam/core/thread_priority.hpp"
#include "slam/core/types.hpp"

namespace rgbdquad::quadcontrol {

struct RecorderOptions {
  bool enabled = false;  ///< built-in default off (tests, tools); the shipped config turns it on
  std::string dir;       ///< output folder, created if missing
  /// RGB and depth of every n-th frame. 1: SLAM replayed on 1 frame in 6 lost track where the
  /// flight's SLAM on every frame did not (docs/recording.md), and storing the link's
  /// payloads as they are costs no encoding; the price is size (~the link's rate,
  /// docs/recording.md).
  int image_every_n_frames = 1;
  /// Depth also as foxglove.RawImage 16UC1 every n-th frame (0: never), for Foxglove's Image panel
  /// (it cannot decode RVL): 30 = 1 Hz at 30 fps, ~0.1 MB per preview after zstd.
  int depth_preview_every_n_frames = 30;
  int jpeg_quality = 90;  ///< frames that came decoded only: 90, the streamer's default (same look)
  int map_period_ms = 10000;  ///< the whole coloured cloud every 10 s (it grows to ~10^5 points)
  std::size_t map_max_points = 20000;  ///< decimated to this (20000 x 15 B ~ 0.3 MB per message)
  int flush_period_ms = 1000;          ///< chunk closed at least this often: the loss on a SIGKILL
  double max_file_mb = 512.0;          ///< rotate: ~1 min per file at the live stream's ~7 MB/s
  /// This run's budget; its oldest files are deleted beyond it: ~9 min of every frame at ~7 MB/s
  /// (the end of a flight is what a crash investigation needs).
  double max_total_mb = 4096.0;
  std::size_t queue_max_events = 1024;  ///< ~10 s of telemetry at ~100 events/s
  /// Frames with images waiting for the writer: 90 = 3 s at 30 fps, so a writer thread starved for
  /// seconds by the real-time threads of a loaded machine loses no image (4 lost 876 of 1218 in a
  /// HIL flight at load ~7); the byte bound below caps the memory.
  std::size_t queue_max_frames = 90;
  /// Bytes the queue may hold (payloads and pixels it keeps alive). 48 MiB: 3 s of the live stream
  /// (JPEG + RVL ~0.3 MB per frame at 30 fps = 27 MB) with room for the map; or ~30 frames that
  /// must be encoded here (1.5 MB of pixels each). Beyond it images are dropped (counted).
  double queue_max_mb = 48.0;
  bool zstd = true;
  /// True when every field is in range; else false and, if error is not null, which one and why.
  bool is_valid(std::string* error) const;
  nlohmann::json to_json() const;
};

// Value types handed to the recorder (copies; nothing refers back into the ground station).
struct FrameRecord {
  std::int64_t sequence = 0, capture_us = 0, received_us = 0;
  double link_latency_ms = 0.0;
  double fps = 0.0;
  cv::Mat rgb, depth;  ///< BGR8 / 16UC1, shared headers (the frame is never written after
                       ///< delivery); kept only when an image must be encoded here or previewed
  slam::Intrinsics intrinsics;
  EncodedImage rgb_encoded, depth_encoded;  ///< the link's payloads (stored as they are)
  int width_px = 0, height_px = 0;          ///< of the (registered) images
  bool images = false;   ///< this frame's images are recorded (every n-th, not dropped)
  bool preview = false;  ///< also write the 16UC1 preview and the calibration
  /// Memory this record keeps alive (payloads, pixels): what the queue's byte bound counts.
  std::size_t bytes() const;
};
struct PoseRecord {
  std::int64_t sequence = 0, capture_us = 0, received_us = 0, pose_us = 0;
  bool tracking = false;
  std::string slam_state;
  std::size_t inliers = 0;
  double slam_latency_ms = 0.0;
  std::uint64_t session = 0;
  Eigen::Isometry3d T_floor_cam = Eigen::Isometry3d::Identity();
  CraftPose pose, setpoint;
  std::string flight_state;
  /// The camera's attitude given to SLAM with the frame (CameraFrame::q_ned_cam): a replay feeds
  /// SLAM the same rotation prior and gravity direction as the flight did.
  std::optional<Eigen::Quaterniond> q_ned_cam;
};
struct CommandRecord {
  std::uint32_t seq = 0;
  std::int64_t send_us = 0;
  std::string flight_state;
  StickCommand stick;
  PwmCommand pwm;
  std::int64_t pose_capture_us = -1, pose_us = -1;
};
struct ReplyRecord {
  std::int64_t received_us = 0;
  rgbd_control::Reply reply;
};
struct EventRecord {
  std::int64_t t_us = 0;
  int level = 2;       ///< foxglove.Log levels: 1 debug, 2 info, 3 warning, 4 error, 5 fatal
  std::string source;  ///< "state", "failsafe", "slam", "stream", "recorder"
  std::string text;
};
struct MapRecord {
  std::int64_t t_us = 0;
  std::vector<ColouredPoint> points;
};

struct RecorderStats {
  bool enabled = false, failed = false;
  std::string error, file;
  std::uint64_t messages = 0, bytes = 0, files = 0, deleted_files = 0;
  std::uint64_t dropped_queue_full = 0, dropped_after_failure = 0;
  std::uint64_t images_dropped =
      0;  ///< frames whose images found the frame slots full (telemetry kept)
  std::uint64_t frames_recorded = 0;
  std::uint64_t frames_encoded_here = 0;  ///< recorded frames that came without the link's payloads
  std::uint64_t queued_bytes = 0,
                queued_bytes_peak = 0;  ///< the queue's bytes now / the most so far
  double encode_ms_per_frame = 0.0;     ///< writer thread CPU per recorded frame (images + JSON)
  double writer_cpu_ms = 0.0;  ///< writer thread CPU since start (everything it encoded and wrote)
  // Live figures for the dashboard's history plots (from the recorded stream).
  std::optional<double> capture_to_command_ms, pose_to_command_ms;
};

class FlightRecorder {
 public:
  using Logger = std::function<void(const std::string&)>;
  /// Opens `<dir>/<stem>-000.mcap` and starts the writer thread; nullptr with `error` on failure.
  /// `logger` gets the recorder's own events (rotation, deletion, failure), one line each.
  static std::unique_ptr<FlightRecorder> open(const RecorderOptions& options,
                                              const std::string& stem, Logger logger,
                                              std::string* error);
  ~FlightRecorder();  ///< drains the queue, writes the summary, joins the thread
  FlightRecorder(const FlightRecorder&) = delete;
  FlightRecorder& operator=(const FlightRecorder&) = delete;

  /// `rgb_encoded` / `depth_encoded`: the link's payloads when the frame came encoded (stored as
  /// they are); absent, the recorder encodes `rgb` (JPEG) and `depth` (RVL) on its writer thread.
  void frame(std::int64_t sequence, std::int64_t capture_us, std::int64_t received_us,
             double link_latency_ms, double fps, const cv::Mat& rgb, const cv::Mat& depth,
             const slam::Intrinsics& intrinsics, const EncodedImage& rgb_encoded = {},
             const EncodedImage& depth_encoded = {});
  void pose(PoseRecord record);
  void command(CommandRecord record);
  void reply(std::int64_t received_us, const rgbd_control::Reply& reply);
  /// Logs a transition once: called with the controller's state and last event on every command,
  /// records an event only when either changed.
  void status(std::int64_t now_us, const std::string& state, const std::string& last_event);
  void event(EventRecord record);
  /// True when a map snapshot is due (then call map()); cheap, for the caller to skip the copy.
  bool map_due(std::int64_t now_us);
  void map(MapRecord record);
  RecorderStats stats() const;

 private:
  using Event =
      std::variant<FrameRecord, PoseRecord, CommandRecord, ReplyRecord, EventRecord, MapRecord>;
  class Writer;
  FlightRecorder(RecorderOptions options, std::unique_ptr<Writer> writer, Logger logger);
  void push(Event e, bool is_frame);
  /// The writer thread: WriterLoop (the .cpp) drains the queue into the file until stopped.
  void run();
  class WriterLoop;

  RecorderOptions options_;
  Logger logger_;
  std::unique_ptr<Writer> writer_;  ///< touched by the writer thread only (after construction)

  // Taken by the real-time frame / SLAM / firmware threads and by the normal-policy writer: with
  // priority inheritance the writer holding it runs at the waiting producer's priority.
  mutable slam::PriorityInheritanceMutex mutex_;
  std::condition_variable_any wake_;
  std::deque<Event> queue_;  ///< events not yet written (the writer pops each after writing it)
  std::size_t frames_queued_ = 0;  ///< frames in queue_ holding images
  std::size_t queued_bytes_ = 0;   ///< sum of the events' bytes in queue_
  bool stop_ = false;
  std::int64_t frames_seen_ = 0;
  std::int64_t last_map_us_ = -1;
  std::string last_state_, last_event_;
  std::int64_t last_commanded_capture_us_ = -1;
  RecorderStats stats_;
  std::thread thread_;
};

/// For the dashboard's /api/state "recording" object.
nlohmann::json to_json(const RecorderStats& stats);

/// RFC 4648 base64 (JSON-encoded MCAP messages carry bytes fields as base64, Foxglove's rule).
std::string base64_encode(const std::string& bytes);
std::string base64_encode(const std::uint8_t* data, std::size_t size);

}  // namespace rgbdquad::quadcontrol
