// SLAM-link session (protocol/spec/messages.json, link "slam"): the socket-free half of
// slam-server. It answers SlamHello with its own SlamHello (refusing an incompatible peer), and
// every RgbdFrame with exactly one PoseUpdate computed by the SLAM pipeline (sequential mode, so
// the answer belongs to that very frame). The pipeline is created on the first frame from the
// intrinsics and depth scale the frame carries.
//
// Not thread-safe: one session per connection, used by that connection's thread.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rgbdquad/protocol/messages.hpp"
#include "slam/pipeline/pipeline.hpp"

namespace slam {

class SlamLinkSession {
 public:
  /// `options.mode` is forced to kSequential (one reply per frame).
  SlamLinkSession(PipelineOptions options, std::string server_name);

  /// Handles one decoded message. Returns the replies to send (possibly none). A message that
  /// cannot be used (wrong type for this direction, incompatible peer, frame without hello,
  /// unsupported encoding, inconsistent sizes) gives no reply and an explanation in `error`;
  /// `fatal` is set when the connection should be closed (incompatible peer).
  std::vector<rgbdquad::protocol::Message> on_message(const rgbdquad::protocol::Message& message,
                                                      std::string* error, bool* fatal);

  std::size_t frames_processed() const { return frames_; }
  /// The pipeline (null before the first frame); finish() it before reading results.
  Pipeline* pipeline() { return pipeline_.get(); }

 private:
  std::optional<RgbdFrame> to_frame(const rgbdquad::protocol::RgbdFrame& m, std::string* error) const;

  PipelineOptions options_;
  std::string server_name_;
  bool hello_received_ = false;
  std::unique_ptr<Pipeline> pipeline_;
  Intrinsics intrinsics_;
  std::size_t frames_ = 0;
};

}  // namespace slam
