// Value types of every message on the RGB-D stream and the SLAM link, one struct per message of
// protocol/spec/messages.json with the same field names (units in names; see docs/protocol.md).
// Plain values: copyable, no invariants enforced here; `validate()` and the codecs enforce them.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include "rgbdquad/protocol/spec_generated.hpp"

namespace rgbdquad::protocol {

/// Random bytes of one side of a stream connection (spec protocol.stream_auth.nonce_bytes).
using StreamNonce = std::array<std::uint8_t, kStreamAuthNonceBytes>;
/// SipHash-2-4 tag (spec protocol.stream_auth.tag_bytes).
using StreamTag = std::array<std::uint8_t, kStreamAuthTagBytes>;

/// Pinhole intrinsics of the image a stream carries; distortion in OpenCV order k1 k2 p1 p2 k3.
struct CameraIntrinsics {
  double fx_px = 1.0;
  double fy_px = 1.0;
  double cx_px = 0.0;
  double cy_px = 0.0;
  std::array<double, 5> distortion{};
};

/// Fixed-size part of an image frame (spec struct ImageFrame without the payload bytes).
struct FrameHeader {
  std::uint32_t sequence = 0;              ///< per stream, +1 per captured frame from 0
  std::uint64_t capture_timestamp_us = 0;  ///< capture time, sensor clock
  std::uint64_t send_timestamp_us = 0;     ///< sender's monotonic clock at send
  std::uint16_t width = 0;                 ///< px
  std::uint16_t height = 0;                ///< px
  PixelFormat pixel_format = PixelFormat::kRgb8;
  Encoding encoding = Encoding::kRaw;
  std::uint32_t payload_length = 0;  ///< bytes; must equal payload.size() when encoding
};

/// One image (spec struct ImageFrame); the stream's Frame message carries exactly one.
struct ImageFrame {
  FrameHeader header;
  std::vector<std::uint8_t> payload;  ///< encoded pixels, see header.encoding
};

/// Rigid transform T_a_b (maps points in frame b to frame a). Quaternion order x y z w (Hamilton).
struct Pose3 {
  std::array<double, 3> t_m{};
  std::array<double, 4> q_xyzw{0.0, 0.0, 0.0, 1.0};
};

/// The camera's attitude at capture from the craft's IMU (R_nav_cam, nav gravity-aligned: NED for
/// the APM), when the sender has one; the receiver uses only its change between frames.
struct CameraAttitude {
  bool valid = false;
  std::array<double, 4> q_xyzw{0.0, 0.0, 0.0, 1.0};  ///< (0, 0, 0, 1) when not valid
};

/// The camera's accelerometer at the capture of the image it travels with (spec AccelSample, since
/// version 2): specific force in the accelerometer's own axes (Kinect v1: libfreenect's
/// freenect_get_mks_accel), m/s^2; the receiver rotates it into the optical frame
/// (rgbdquad/camera/tum_cameras.hpp kKinectV1Accelerometer). Decoded from a version-1 body as
/// not valid.
struct AccelSample {
  bool valid = false;
  std::uint64_t capture_timestamp_us = 0;  ///< sensor clock of the image's capture_timestamp_us
  std::array<double, 3> f_mps2{};          ///< x y z; zeros when not valid
};

/// Stream, sender -> receiver, first message on each connection.
struct Handshake {
  std::uint16_t protocol_version = kProtocolVersion;
  std::uint64_t schema_hash = kSchemaHash;
  StreamKind stream_kind = StreamKind::kRgb;
  std::uint16_t width = 0;
  std::uint16_t height = 0;
  PixelFormat pixel_format = PixelFormat::kRgb8;
  Encoding encoding = Encoding::kRaw;
  CameraIntrinsics intrinsics;
  double depth_scale_units_per_m = 0.0;  ///< DEPTH16 units per metre (1000 Kinect, 5000 TUM); 0 RGB
  std::string device_id;                 ///< printable ASCII, <= kMaxStringBytes
  StreamNonce sender_nonce{};            ///< random per connection (stream_auth.hpp)
  StreamTag mac{};                       ///< over the receiver's challenge and this body
};

/// Stream, receiver -> sender: answer to the Handshake.
struct HandshakeAck {
  bool accepted = false;
  std::string reason;  ///< printable ASCII, empty when accepted
  StreamTag mac{};     ///< over both nonces and this body (stream_auth.hpp)
};

/// Stream, receiver -> sender: first message on each connection, the challenge the Handshake's
/// mac must cover.
struct StreamChallenge {
  StreamNonce receiver_nonce{};
};

/// Stream, sender -> receiver: one image, sent only against a credit, always the newest held.
struct Frame {
  ImageFrame image;
  AccelSample accel;  ///< RGB stream: the sample nearest the image; depth stream: not valid
};

/// Stream, receiver -> sender: grants `credits` more frames (1..kMaxCreditsPerRequest).
struct FrameRequest {
  std::uint16_t credits = 1;
  std::uint32_t last_received_sequence = 0xFFFFFFFFu;  ///< 0xFFFFFFFF: none yet (diagnostics)
};

/// SLAM link, both ways, first message.
struct SlamHello {
  std::uint16_t protocol_version = kProtocolVersion;
  std::uint64_t schema_hash = kSchemaHash;
  std::string peer_name;
  /// Client: the flight's map (random per flight; 0 = a new map the server names). Server: the
  /// session it serves. Reconnecting with a held session's id continues its map and world frame.
  std::uint64_t session_id = 0;
  bool resumed = false;              ///< server: an existing session continues
  std::uint32_t session_frames = 0;  ///< server: frames already in the session's map
  std::string refusal;               ///< server: non-empty = refused (then closed), with the reason
};

/// SLAM link, quad-control -> slam-server: a registered RGB-D pair.
struct RgbdFrame {
  std::uint32_t pair_sequence = 0;
  CameraIntrinsics intrinsics;  ///< of the RGB image; depth is registered to it
  double depth_scale_units_per_m = 1000.0;
  CameraAttitude attitude;
  ImageFrame rgb;     ///< pixel_format RGB8
  ImageFrame depth;   ///< pixel_format DEPTH16
  AccelSample accel;  ///< the rgb image's accelerometer sample, sensor axes
};

/// SLAM link, slam-server -> quad-control: tracking result for one RgbdFrame.
struct PoseUpdate {
  std::uint32_t pair_sequence = 0;
  std::uint64_t timestamp_us = 0;  ///< capture time of the RGB image, sensor clock
  TrackingState tracking_state = TrackingState::kInitializing;
  Pose3 T_world_cam;  ///< maps camera points to world
  Pose3 T_prev_cur;   ///< egomotion: maps points in this camera frame to the previous one's
  bool is_keyframe = false;
  std::uint32_t inlier_count = 0;
  /// Map corrections T_world_cam is expressed after (per session, from 0): a change from the
  /// previous PoseUpdate declares that the world frame jumped in between (spec doc).
  std::uint32_t map_correction_count = 0;
};

struct PoseGraphNode {
  std::uint32_t node_id = 0;
  std::uint64_t timestamp_us = 0;
  Pose3 T_world_node;
};

struct PoseGraphEdge {
  std::uint32_t from_id = 0;
  std::uint32_t to_id = 0;
  EdgeKind kind = EdgeKind::kOdometry;
  Pose3 T_from_to;  ///< maps points in 'to' to 'from'
};

/// SLAM link: pose-graph snapshot before or after optimisation.
struct PoseGraph {
  std::uint32_t revision = 0;
  std::uint64_t timestamp_us = 0;
  GraphStage stage = GraphStage::kBeforeOptimisation;
  std::vector<PoseGraphNode> nodes;  ///< <= kMaxGraphNodes
  std::vector<PoseGraphEdge> edges;  ///< <= kMaxGraphEdges
};

/// SLAM link: 2D floor map, row-major cells; cell (row r, col c) covers world
/// x in origin_x_m + [c, c+1) * resolution_m, y in origin_y_m + [r, r+1) * resolution_m.
struct FloorMap {
  std::uint32_t revision = 0;
  std::uint64_t timestamp_us = 0;
  double resolution_m = 0.05;  ///< m per cell
  double origin_x_m = 0.0;
  double origin_y_m = 0.0;
  std::uint16_t width_cells = 0;
  std::uint16_t height_cells = 0;
  CellFormat cell_format = CellFormat::kOccupancyU8;
  std::vector<std::uint8_t> cells;  ///< width_cells * height_cells bytes
};

/// Any message; the alternative index is not the wire id, use message_type().
using Message = std::variant<Handshake, HandshakeAck, Frame, FrameRequest, SlamHello, RgbdFrame,
                             PoseUpdate, PoseGraph, FloorMap, StreamChallenge>;

/// Wire id of the message held.
MessageType message_type(const Message& message);

}  // namespace rgbdquad::protocol
