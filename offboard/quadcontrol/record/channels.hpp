// The recorder's channels: topic, schema name and JSON Schema of each, defined once here and listed
// in docs/recording.md. Foxglove well-known schemas (https://docs.foxglove.dev/docs/visualization/
// message-schemas) where one fits, so Foxglove's 3D / Image / Log panels show them as they are;
// `rgbdquad.*` JSON schemas for our own messages. Every message is JSON ("json" encoding); bytes
// fields are base64 strings (Foxglove's JSON rule).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace rgbdquad::quadcontrol::record {

struct ChannelSpec {
  std::string topic;
  std::string schema_name;
  std::string schema_json;  ///< JSON Schema (draft 2020-12 subset Foxglove reads)
};

// Topics (docs/recording.md).
inline constexpr const char* kTopicRgb =
    "/camera/rgb/compressed";  // foxglove.CompressedImage (jpeg)
/// Depth of every recorded frame as the link carried it (RVL / zstd-delta): Foxglove has no
/// schema for these, so a project channel (docs/recording.md says how to decode it).
inline constexpr const char* kTopicDepthCompressed =
    "/camera/depth/compressed";  // rgbdquad.CompressedDepth
/// A 1 Hz preview of the depth that Foxglove's Image panel shows as it is.
inline constexpr const char* kTopicDepth = "/camera/depth/raw";  // foxglove.RawImage (16UC1)
inline constexpr const char* kTopicCalibration =
    "/camera/calibration";                               // foxglove.CameraCalibration
inline constexpr const char* kTopicTf = "/tf";           // foxglove.FrameTransform floor->camera
inline constexpr const char* kTopicPose = "/slam/pose";  // foxglove.PoseInFrame (floor)
inline constexpr const char* kTopicSetpoint = "/control/setpoint";  // foxglove.PoseInFrame (floor)
inline constexpr const char* kTopicMap = "/map/cloud";              // foxglove.PointCloud (floor)
inline constexpr const char* kTopicLog = "/log";                    // foxglove.Log
inline constexpr const char* kTopicFrame = "/stream/frame";         // rgbdquad.StreamFrame
inline constexpr const char* kTopicTracking = "/slam/tracking";     // rgbdquad.Tracking
inline constexpr const char* kTopicLatency = "/latency";            // rgbdquad.StageLatency
inline constexpr const char* kTopicCommand = "/control/command";    // rgbdquad.Command
inline constexpr const char* kTopicReply = "/firmware/reply";       // rgbdquad.FirmwareReply
inline constexpr const char* kTopicEvent = "/events";               // rgbdquad.Event
inline constexpr const char* kTopicRecorder = "/recorder/stats";    // rgbdquad.RecorderStats

/// Every channel, in the order they are registered (channel id = index + 1).
const std::vector<ChannelSpec>& channel_specs();
/// Index of `topic` in channel_specs(); channel_specs().size() for a topic not in the table.
std::size_t channel_index(const char* topic);

}  // namespace rgbdquad::quadcontrol::record
