// Channel definitions: see channels.hpp. The schemas are written from Foxglove's published field
// lists (names, types, units); ours follow the house rule of units in names.
#include "record/channels.hpp"

#include <nlohmann/json.hpp>

namespace rgbdquad::quadcontrol::record {

namespace {
using nlohmann::json;

json num() { return {{"type", "number"}}; }
json integer() { return {{"type", "integer"}}; }
json str() { return {{"type", "string"}}; }
json boolean() { return {{"type", "boolean"}}; }
json bytes() { return {{"type", "string"}, {"contentEncoding", "base64"}}; }
json num_array() { return {{"type", "array"}, {"items", num()}}; }
json object(const std::string& title, json properties) {
  return {{"title", title}, {"type", "object"}, {"properties", std::move(properties)}};
}
json timestamp() { return object("time", {{"sec", integer()}, {"nsec", integer()}}); }
json vector3() { return object("Vector3", {{"x", num()}, {"y", num()}, {"z", num()}}); }
json quaternion() {
  return object("Quaternion", {{"x", num()}, {"y", num()}, {"z", num()}, {"w", num()}});
}
json pose() { return object("Pose", {{"position", vector3()}, {"orientation", quaternion()}}); }
json xyzyaw() {
  return object("CraftPose", {{"x_m", num()}, {"y_m", num()}, {"z_m", num()}, {"yaw_deg", num()}});
}

ChannelSpec spec(const char* topic, const std::string& name, json schema) {
  schema["$schema"] = "https://json-schema.org/draft/2020-12/schema";
  return ChannelSpec{topic, name, schema.dump()};
}

std::vector<ChannelSpec> make_specs() {
  std::vector<ChannelSpec> s;
  s.push_back(spec(kTopicRgb, "foxglove.CompressedImage",
                   object("foxglove.CompressedImage", {{"timestamp", timestamp()},
                                                       {"frame_id", str()},
                                                       {"data", bytes()},
                                                       {"format", str()}})));
  s.push_back(spec(kTopicDepth, "foxglove.RawImage",
                   object("foxglove.RawImage", {{"timestamp", timestamp()},
                                                {"frame_id", str()},
                                                {"width", integer()},
                                                {"height", integer()},
                                                {"encoding", str()},
                                                {"step", integer()},
                                                {"data", bytes()}})));
  s.push_back(spec(kTopicCalibration, "foxglove.CameraCalibration",
                   object("foxglove.CameraCalibration", {{"timestamp", timestamp()},
                                                         {"frame_id", str()},
                                                         {"width", integer()},
                                                         {"height", integer()},
                                                         {"distortion_model", str()},
                                                         {"D", num_array()},
                                                         {"K", num_array()},
                                                         {"R", num_array()},
                                                         {"P", num_array()}})));
  s.push_back(spec(kTopicTf, "foxglove.FrameTransform",
                   object("foxglove.FrameTransform", {{"timestamp", timestamp()},
                                                      {"parent_frame_id", str()},
                                                      {"child_frame_id", str()},
                                                      {"translation", vector3()},
                                                      {"rotation", quaternion()}})));
  const json pose_in_frame = object(
      "foxglove.PoseInFrame", {{"timestamp", timestamp()}, {"frame_id", str()}, {"pose", pose()}});
  s.push_back(spec(kTopicPose, "foxglove.PoseInFrame", pose_in_frame));
  s.push_back(spec(kTopicSetpoint, "foxglove.PoseInFrame", pose_in_frame));
  const json field = object("foxglove.PackedElementField",
                            {{"name", str()}, {"offset", integer()}, {"type", integer()}});
  s.push_back(spec(kTopicMap, "foxglove.PointCloud",
                   object("foxglove.PointCloud", {{"timestamp", timestamp()},
                                                  {"frame_id", str()},
                                                  {"pose", pose()},
                                                  {"point_stride", integer()},
                                                  {"fields", {{"type", "array"}, {"items", field}}},
                                                  {"data", bytes()}})));
  s.push_back(spec(kTopicLog, "foxglove.Log",
                   object("foxglove.Log", {{"timestamp", timestamp()},
                                           {"level", integer()},
                                           {"message", str()},
                                           {"name", str()},
                                           {"file", str()},
                                           {"line", integer()}})));
  s.push_back(spec(kTopicFrame, "rgbdquad.StreamFrame",
                   object("rgbdquad.StreamFrame", {{"sequence", integer()},
                                                   {"capture_us", integer()},
                                                   {"received_us", integer()},
                                                   {"link_latency_ms", num()},
                                                   {"fps", num()},
                                                   {"images_recorded", boolean()}})));
  s.push_back(spec(kTopicTracking, "rgbdquad.Tracking",
                   object("rgbdquad.Tracking", {{"sequence", integer()},
                                                {"capture_us", integer()},
                                                {"pose_us", integer()},
                                                {"tracking", boolean()},
                                                {"slam_state", str()},
                                                {"inliers", integer()},
                                                {"session", integer()},
                                                {"flight_state", str()},
                                                {"pose", xyzyaw()},
                                                {"setpoint", xyzyaw()},
                                                {"position_error_m", num()},
                                                {"height_error_m", num()}})));
  s.push_back(spec(kTopicLatency, "rgbdquad.StageLatency",
                   object("rgbdquad.StageLatency", {{"sequence", integer()},
                                                    {"capture_us", integer()},
                                                    {"link_ms", num()},
                                                    {"capture_to_received_ms", num()},
                                                    {"received_to_pose_ms", num()},
                                                    {"slam_ms", num()}})));
  s.push_back(spec(
      kTopicCommand, "rgbdquad.Command",
      object("rgbdquad.Command",
             {{"seq", integer()},
              {"send_us", integer()},
              {"flight_state", str()},
              {"armed", boolean()},
              {"stick_pct",
               object("Sticks",
                      {{"roll", num()}, {"pitch", num()}, {"yaw", num()}, {"throttle", num()}})},
              {"pwm_us", object("Pwm", {{"roll", integer()},
                                        {"pitch", integer()},
                                        {"throttle", integer()},
                                        {"yaw", integer()}})},
              {"pose_capture_us", integer()},
              {"pose_us", integer()},
              {"capture_to_command_ms", num()},
              {"pose_to_command_ms", num()}})));
  s.push_back(spec(kTopicReply, "rgbdquad.FirmwareReply",
                   object("rgbdquad.FirmwareReply", {{"received_us", integer()},
                                                     {"status", integer()},
                                                     {"seq", integer()},
                                                     {"state", str()},
                                                     {"err", str()},
                                                     {"out_us", num_array()},
                                                     {"clamped", integer()},
                                                     {"att_mrad", num_array()},
                                                     {"att_age_ms", integer()},
                                                     {"imu_raw", num_array()},
                                                     {"imu_age_ms", integer()}})));
  s.push_back(spec(
      kTopicEvent, "rgbdquad.Event",
      object("rgbdquad.Event",
             {{"t_us", integer()}, {"level", integer()}, {"source", str()}, {"text", str()}})));
  s.push_back(spec(kTopicRecorder, "rgbdquad.RecorderStats",
                   object("rgbdquad.RecorderStats", {{"messages", integer()},
                                                     {"bytes", integer()},
                                                     {"dropped_queue_full", integer()},
                                                     {"images_dropped", integer()},
                                                     {"frames_recorded", integer()},
                                                     {"encode_ms_per_frame", num()},
                                                     {"queued", integer()}})));
  return s;
}
}  // namespace

const std::vector<ChannelSpec>& channel_specs() {
  static const std::vector<ChannelSpec> specs = make_specs();  // immutable table, built once
  return specs;
}

}  // namespace rgbdquad::quadcontrol::record
