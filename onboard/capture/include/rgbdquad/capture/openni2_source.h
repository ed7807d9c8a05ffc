// Any OpenNI2 device (PrimeSense/ASUS Xtion, Kinect with a third-party driver): 640x480 RGB888
// and 1 mm depth at 30 fps. Hardware depth-to-colour registration is enabled when the device
// supports it; otherwise depth arrives unregistered (registered_to_rgb = false) and the
// pipeline's DepthRegistration stage registers it with the configured calibration.
// Frames are stamped with the injected clock when read (the same clock as every other source).
//
// Thread safety: next() on one thread; stop() from any thread (next() notices within
// kWaitTimeoutMs).
#pragma once

#include <atomic>
#include <memory>
#include <string>

#include "rgbdquad/capture/clock.h"
#include "rgbdquad/capture/frame_source.h"

namespace rgbdquad::capture {

struct OpenNi2Options {
  std::string uri;  // empty = any device
  bool is_valid(std::string* error) const;
};

class OpenNi2Source final : public FrameSource {
 public:
  // Throws std::runtime_error with OpenNI2's reason when no device can be opened.
  OpenNi2Source(const OpenNi2Options& options, Clock* clock);
  ~OpenNi2Source() override;
  OpenNi2Source(const OpenNi2Source&) = delete;
  OpenNi2Source& operator=(const OpenNi2Source&) = delete;

  std::optional<SourceFrame> next() override;
  void stop() override { stopped_ = true; }
  std::string error() const override { return error_; }
  std::string describe() const override;
  bool hardware_registration() const { return hardware_registration_; }

 private:
  struct Device;  // OpenNI2 objects, kept out of this header
  OpenNi2Options options_;
  Clock* clock_;
  std::unique_ptr<Device> device_;
  bool hardware_registration_ = false;
  std::atomic<bool> stopped_{false};
  std::string error_;
};

}  // namespace rgbdquad::capture
