// OpenNI2 capture source.
#include "rgbdquad/capture/openni2_source.h"

#include <OpenNI.h>

#include <cstring>
#include <stdexcept>

namespace rgbdquad::capture {
namespace {
// How long one wait for a frame blocks before stop() is rechecked: 100 ms = 3 frame periods.
constexpr int kWaitTimeoutMs = 100;
// Consecutive wait time-outs after which the device is declared gone: 50 x 100 ms = 5 s.
constexpr int kMaxConsecutiveTimeouts = 50;
}  // namespace

struct OpenNi2Source::Device {
  openni::Device device;
  openni::VideoStream depth;
  openni::VideoStream color;
};

bool OpenNi2Options::is_valid(std::string* /*error*/) const { return true; }

OpenNi2Source::OpenNi2Source(const OpenNi2Options& options, Clock* clock)
    : options_(options), clock_(clock), device_(std::make_unique<Device>()) {
  auto fail = [](const std::string& what) {
    throw std::runtime_error("OpenNI2: " + what + ": " + openni::OpenNI::getExtendedError());
  };
  if (openni::OpenNI::initialize() != openni::STATUS_OK) fail("initialize failed");
  const char* uri = options_.uri.empty() ? openni::ANY_DEVICE : options_.uri.c_str();
  if (device_->device.open(uri) != openni::STATUS_OK) {
    device_.reset();  // (no OpenNI::shutdown(): see the destructor)
    fail("cannot open device '" + options_.uri + "'");
  }
  auto open_stream = [&](openni::VideoStream& s, openni::SensorType type,
                         openni::PixelFormat format) {
    if (s.create(device_->device, type) != openni::STATUS_OK) return false;
    openni::VideoMode mode;
    mode.setResolution(kKinectWidthPx, kKinectHeightPx);
    mode.setFps(30);
    mode.setPixelFormat(format);
    // Devices that refuse 640x480@30 keep their default mode; validation then drops the frames
    // as malformed and the counters say so.
    s.setVideoMode(mode);
    return s.start() == openni::STATUS_OK;
  };
  if (!open_stream(device_->depth, openni::SENSOR_DEPTH, openni::PIXEL_FORMAT_DEPTH_1_MM) ||
      !open_stream(device_->color, openni::SENSOR_COLOR, openni::PIXEL_FORMAT_RGB888)) {
    device_->depth.destroy();
    device_->color.destroy();
    device_->device.close();
    device_.reset();
    fail("cannot start depth and colour streams");
  }
  if (device_->device.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR) &&
      device_->device.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR) ==
          openni::STATUS_OK) {
    hardware_registration_ = true;
  }
}

OpenNi2Source::~OpenNi2Source() {
  if (device_) {
    device_->depth.stop();
    device_->color.stop();
    device_->depth.destroy();
    device_->color.destroy();
    device_->device.close();
    device_.reset();
    // No OpenNI::shutdown() here: it unloads the driver libraries while driver threads may still
    // run (Debian's OpenNI2 2.2 DummyDevice then crashes in unmapped code). OpenNI::initialize()
    // is idempotent, so a later source reuses the loaded drivers; the OS frees them at exit.
  }
}

std::string OpenNi2Source::describe() const {
  return "openni2:" + (options_.uri.empty() ? std::string("any") : options_.uri) +
         (hardware_registration_ ? " (hardware registration)" : " (software registration)");
}

std::optional<SourceFrame> OpenNi2Source::next() {
  openni::VideoStream* streams[] = {&device_->depth, &device_->color};
  int timeouts = 0;
  while (!stopped_) {
    int ready = -1;
    const openni::Status status =
        openni::OpenNI::waitForAnyStream(streams, 2, &ready, kWaitTimeoutMs);
    if (status == openni::STATUS_TIME_OUT) {
      if (++timeouts >= kMaxConsecutiveTimeouts) {
        error_ = "no frame for 5 s";
        return std::nullopt;
      }
      continue;
    }
    if (status != openni::STATUS_OK) {
      error_ = std::string("waitForAnyStream: ") + openni::OpenNI::getExtendedError();
      return std::nullopt;
    }
    openni::VideoFrameRef frame;
    if (streams[ready]->readFrame(&frame) != openni::STATUS_OK || !frame.isValid()) continue;
    const int w = frame.getWidth();
    const int h = frame.getHeight();
    const auto* data = static_cast<const std::uint8_t*>(frame.getData());
    const auto bytes = static_cast<std::size_t>(frame.getDataSize());
    if (ready == 0) {
      DepthFrame f;
      f.capture_timestamp_us = clock_->now_us();
      f.width = w;
      f.height = h;
      f.units_per_m = kMillimetreUnitsPerM;
      f.registered_to_rgb = hardware_registration_;
      // A short buffer yields a short image: validation counts it as malformed.
      f.depth.resize(std::min(bytes / 2, static_cast<std::size_t>(w) * h));
      std::memcpy(f.depth.data(), data, f.depth.size() * 2);
      return SourceFrame(std::move(f));
    }
    RgbFrame f;
    f.capture_timestamp_us = clock_->now_us();
    f.width = w;
    f.height = h;
    f.rgb.assign(data, data + std::min(bytes, static_cast<std::size_t>(w) * h * 3));
    return SourceFrame(std::move(f));
  }
  return std::nullopt;
}

}  // namespace rgbdquad::capture
