// One interface for every capture source (Kinect via libfreenect, OpenNI2 devices, TUM dataset
// replay, fakenect replay through libfreenect). Adding a source = implementing FrameSource and
// adding a case to make_frame_source() (source_factory.h); the HIL rig's rendered-frame source
// plugs in the same way.
//
// Thread safety: next() is called by one consumer thread; stop() may be called from any thread
// and makes a blocked next() return std::nullopt promptly.
#pragma once

#include <optional>
#include <string>

#include "rgbdquad/capture/frame.h"

namespace rgbdquad::capture {

class FrameSource {
 public:
  virtual ~FrameSource() = default;

  // Blocks until the next RGB or depth frame. Returns std::nullopt at end of stream (replays),
  // after stop(), or on an unrecoverable device error (then error() says why).
  virtual std::optional<SourceFrame> next() = 0;
  virtual void stop() = 0;
  // Empty while healthy.
  virtual std::string error() const = 0;
  // Short description for logs, e.g. "tum:/data/fr1_xyz (original timing)".
  virtual std::string describe() const = 0;
};

}  // namespace rgbdquad::capture
