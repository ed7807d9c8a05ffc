// Kinect v1 through libfreenect 0.5: 640x480 RGB and depth, stamped with the injected clock when
// libfreenect hands each frame over. The same binary replays a recorded dump when started under
// `fakenect <dumpdir>` (LD_LIBRARY_PATH swaps in libfreenect's fakenect build).
//
// Depth modes:
//  - registered: FREENECT_DEPTH_REGISTERED, millimetres already registered onto RGB by the driver
//    (live Kinect; the default).
//  - disparity: FREENECT_DEPTH_11BIT raw disparity (what fakenect-record stores, and the only mode
//    Debian's fakenect 0.5.3 replays - it asserts 11-bit), converted to millimetres with
//    z = 0.1236 m * tan(raw / 2842.5 + 1.1863) (raw 2047 = no reading). Frames are in the IR
//    camera's view (registered_to_rgb = false): the pipeline's DepthRegistration aligns them.
//
// Accelerometer: a colour image is held back until its event batch ends; the event thread then
// reads the tilt state (freenect_update_tilt_state, a blocking USB control transfer, so never
// inside the frame callback), attaches freenect_get_mks_accel stamped with the clock at the read
// (a few ms after the image's stamp) and queues the image. A failed read, or an all-zero state
// (libfreenect's state before any read; fakenect dumps without accelerometer records), attaches
// none.
//
// Thread safety: libfreenect's event loop runs on an internal thread owned by this object; frames
// cross to the consumer through a small queue (the newest kept when the consumer falls behind).
#pragma once

#include <array>
#include <atomic>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "rgbdquad/capture/clock.h"
#include "rgbdquad/capture/frame_source.h"

struct _freenect_context;
struct _freenect_device;

namespace rgbdquad::capture {

struct FreenectOptions {
  int device_index = 0;
  bool disparity_depth = false;  // true: FREENECT_DEPTH_11BIT disparity -> mm (fakenect dumps)
  // Frames held for a slow consumer before the oldest is dropped: 4 = ~2 RGB+depth pairs.
  std::size_t queue_capacity = 4;

  bool is_valid(std::string* error) const;
};

class FreenectSource final : public FrameSource {
 public:
  // Opens and starts the device; throws std::runtime_error with the reason if there is no
  // Kinect or a mode is refused (start-up boundary). `clock` must outlive the source.
  FreenectSource(const FreenectOptions& options, Clock* clock);
  ~FreenectSource() override;
  FreenectSource(const FreenectSource&) = delete;
  FreenectSource& operator=(const FreenectSource&) = delete;

  std::optional<SourceFrame> next() override;
  void stop() override;
  std::string error() const override;
  std::string describe() const override;
  std::uint64_t queue_overflows() const { return overflows_; }

  // libfreenect C callbacks (public so the C trampolines can reach them).
  void on_depth(const void* data);

  // The disparity -> millimetre conversion used in disparity mode (0 for no reading).
  static std::uint16_t disparity_to_mm(std::uint16_t raw);
  // disparity_to_mm of every 11-bit raw value (index = raw; raw >= 2048 is no reading): what a
  // frame is converted with - 307 200 tan() calls per frame were a fifth of the streamer's CPU.
  using DisparityTable = std::array<std::uint16_t, 2048>;
  static DisparityTable disparity_to_mm_table();
  void on_video(const void* data);

 private:
  void push(SourceFrame frame);
  void event_loop();
  void queue_rgb_with_accel();

  FreenectOptions options_;
  DisparityTable disparity_mm_ = disparity_to_mm_table();
  Clock* clock_;
  _freenect_context* context_ = nullptr;
  _freenect_device* device_ = nullptr;
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<SourceFrame> queue_;
  bool ended_ = false;
  std::string error_;
  std::atomic<bool> stopped_{false};
  std::atomic<std::uint64_t> overflows_{0};
  std::optional<RgbFrame> pending_rgb_;  // event thread only: the image awaiting its reading
  std::thread events_;
};

}  // namespace rgbdquad::capture
