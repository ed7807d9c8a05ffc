// libfreenect capture source.
#include "rgbdquad/capture/freenect_source.h"

#include <libfreenect.h>
#include <pthread.h>

#include <cmath>
#include <cstring>
#include <stdexcept>

namespace rgbdquad::capture {
namespace {

void depth_trampoline(freenect_device* dev, void* depth, uint32_t /*timestamp*/) {
  static_cast<FreenectSource*>(freenect_get_user(dev))->on_depth(depth);
}
void video_trampoline(freenect_device* dev, void* rgb, uint32_t /*timestamp*/) {
  static_cast<FreenectSource*>(freenect_get_user(dev))->on_video(rgb);
}

}  // namespace

bool FreenectOptions::is_valid(std::string* error) const {
  if (device_index < 0) {
    *error = "freenect.device_index must be >= 0";
    return false;
  }
  if (queue_capacity < 2 || queue_capacity > 64) {
    *error = "freenect queue capacity must be 2..64";
    return false;
  }
  return true;
}

FreenectSource::FreenectSource(const FreenectOptions& options, Clock* clock)
    : options_(options), clock_(clock) {
  std::string why;
  if (!options_.is_valid(&why)) throw std::runtime_error(why);
  auto fail = [this](const std::string& what) {
    if (device_ != nullptr) freenect_close_device(device_);
    if (context_ != nullptr) freenect_shutdown(context_);
    device_ = nullptr;
    context_ = nullptr;
    throw std::runtime_error("libfreenect: " + what);
  };
  if (freenect_init(&context_, nullptr) < 0) fail("freenect_init failed");
  freenect_set_log_level(context_, FREENECT_LOG_ERROR);
  // The motor subdevice carries the accelerometer (freenect_update_tilt_state reads nothing
  // without it).
  freenect_select_subdevices(
      context_, static_cast<freenect_device_flags>(FREENECT_DEVICE_CAMERA | FREENECT_DEVICE_MOTOR));
  const int count = freenect_num_devices(context_);
  if (count <= options_.device_index) {
    fail("no Kinect at index " + std::to_string(options_.device_index) + " (" +
         std::to_string(count < 0 ? 0 : count) + " found)");
  }
  if (freenect_open_device(context_, &device_, options_.device_index) < 0) {
    fail("cannot open Kinect " + std::to_string(options_.device_index));
  }
  freenect_set_user(device_, this);
  const freenect_frame_mode video =
      freenect_find_video_mode(FREENECT_RESOLUTION_MEDIUM, FREENECT_VIDEO_RGB);
  const freenect_frame_mode depth = freenect_find_depth_mode(
      FREENECT_RESOLUTION_MEDIUM,
      options_.disparity_depth ? FREENECT_DEPTH_11BIT : FREENECT_DEPTH_REGISTERED);
  if (!video.is_valid || !depth.is_valid || freenect_set_video_mode(device_, video) < 0 ||
      freenect_set_depth_mode(device_, depth) < 0) {
    fail("640x480 RGB / depth mode refused");
  }
  freenect_set_depth_callback(device_, depth_trampoline);
  freenect_set_video_callback(device_, video_trampoline);
  if (freenect_start_depth(device_) < 0 || freenect_start_video(device_) < 0) {
    fail("cannot start streams");
  }
  events_ = std::thread([this] { event_loop(); });
}

FreenectSource::~FreenectSource() {
  stop();
  if (events_.joinable()) events_.join();
  freenect_stop_depth(device_);
  freenect_stop_video(device_);
  freenect_close_device(device_);
  freenect_shutdown(context_);
}

void FreenectSource::event_loop() {
  pthread_setname_np(pthread_self(), "kinect-events");  // top -H / ps -L attribute its CPU
  while (!stopped_) {
    // Blocks until the next USB event (live) or the next dump entry's time (fakenect).
    if (freenect_process_events(context_) < 0) {
      std::lock_guard<std::mutex> lock(mutex_);
      ended_ = true;
      // fakenect returns < 0 at the end of a dump; a live device on USB failure.
      error_ = "freenect_process_events failed (device unplugged or end of fakenect dump)";
      break;
    }
    if (pending_rgb_) queue_rgb_with_accel();
  }
  ready_.notify_all();
}

void FreenectSource::queue_rgb_with_accel() {
  RgbFrame frame = std::move(*pending_rgb_);
  pending_rgb_.reset();
  if (freenect_update_tilt_state(device_) >= 0) {
    freenect_raw_tilt_state* state = freenect_get_tilt_state(device_);
    if (state != nullptr && (state->accelerometer_x != 0 || state->accelerometer_y != 0 ||
                             state->accelerometer_z != 0)) {
      AccelReading reading;
      reading.capture_timestamp_us = clock_->now_us();
      freenect_get_mks_accel(state, &reading.f_mps2[0], &reading.f_mps2[1], &reading.f_mps2[2]);
      frame.accel = reading;
    }
  }
  push(std::move(frame));
}

void FreenectSource::on_depth(const void* data) {
  DepthFrame f;
  f.capture_timestamp_us = clock_->now_us();
  f.width = kKinectWidthPx;
  f.height = kKinectHeightPx;
  f.units_per_m = kMillimetreUnitsPerM;
  f.registered_to_rgb = !options_.disparity_depth;
  f.depth.resize(static_cast<std::size_t>(f.width) * f.height);
  std::memcpy(f.depth.data(), data, f.depth.size() * sizeof(std::uint16_t));
  if (options_.disparity_depth) {
    for (auto& v : f.depth) v = v < disparity_mm_.size() ? disparity_mm_[v] : 0;
  }
  push(std::move(f));
}

void FreenectSource::on_video(const void* data) {
  RgbFrame f;
  f.capture_timestamp_us = clock_->now_us();
  f.width = kKinectWidthPx;
  f.height = kKinectHeightPx;
  const auto* bytes = static_cast<const std::uint8_t*>(data);
  f.rgb.assign(bytes, bytes + static_cast<std::size_t>(f.width) * f.height * 3);
  // Queued by the event loop once the batch ends and the accelerometer is read; an image not yet
  // queued is replaced by a newer one (the queue keeps only the newest anyway).
  pending_rgb_ = std::move(f);
}

void FreenectSource::push(SourceFrame frame) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (queue_.size() >= options_.queue_capacity) {
      queue_.pop_front();
      ++overflows_;
    }
    queue_.push_back(std::move(frame));
  }
  ready_.notify_one();
}

std::optional<SourceFrame> FreenectSource::next() {
  std::unique_lock<std::mutex> lock(mutex_);
  ready_.wait(lock, [this] { return !queue_.empty() || ended_ || stopped_; });
  if (stopped_ || queue_.empty()) return std::nullopt;
  std::optional<SourceFrame> frame(std::move(queue_.front()));
  queue_.pop_front();
  return frame;
}

void FreenectSource::stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopped_ = true;
  }
  ready_.notify_all();
}

std::string FreenectSource::error() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return error_;
}

std::string FreenectSource::describe() const {
  return "freenect:" + std::to_string(options_.device_index) +
         (options_.disparity_depth ? " (11-bit disparity -> mm, software registration)"
                                   : " (registered mm)");
}

std::uint16_t FreenectSource::disparity_to_mm(std::uint16_t raw) {
  // 2047 (and anything above the 11-bit range) means no reading; Magnenat's fit of the Kinect v1
  // disparity-depth relation (OpenKinect wiki, "Imaging Information").
  constexpr std::uint16_t kNoReading = 2047;
  if (raw >= kNoReading) return 0;
  const double z_m = 0.1236 * std::tan(raw / 2842.5 + 1.1863);
  // raw >= ~1084 gives negative or huge values (tan beyond pi/2): not a measurable depth.
  if (!(z_m > 0) || z_m > 10.0) return 0;
  return static_cast<std::uint16_t>(std::lround(z_m * 1000.0));
}

FreenectSource::DisparityTable FreenectSource::disparity_to_mm_table() {
  DisparityTable table{};
  for (std::size_t raw = 0; raw < table.size(); ++raw)
    table[raw] = disparity_to_mm(static_cast<std::uint16_t>(raw));
  return table;
}

}  // namespace rgbdquad::capture
