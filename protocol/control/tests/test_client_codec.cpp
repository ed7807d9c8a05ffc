// C++ ground-station control codec against the golden vectors (the same file the Python codec and
// the firmware core replay) and the spec's ranges.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "rgbd_control/client_codec.h"
#include "rgbd_control/siphash24.h"

namespace {

using nlohmann::json;

json load(const char* path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error(std::string("cannot open ") + path);
  return json::parse(f);
}

const json& vectors() {
  static const json v = load(RGBD_CONTROL_VECTORS);
  return v;
}

TEST(ClientCodec, SipHashVectors) {
  for (const auto& v : vectors()["siphash"]) {
    const auto key = rgbd_control::parse_key_hex(v["key_hex"].get<std::string>());
    ASSERT_TRUE(key);
    const std::string mh = v["msg_hex"];
    std::vector<uint8_t> msg;
    for (size_t i = 0; i < mh.size(); i += 2)
      msg.push_back(static_cast<uint8_t>(std::stoi(mh.substr(i, 2), nullptr, 16)));
    uint8_t tag[8];
    rgbd_control::siphash24_tag_bytes(rgbd_control::siphash24(key->data(), msg.data(), msg.size()),
                                      tag);
    char hex[17];
    for (int i = 0; i < 8; ++i) std::snprintf(hex + 2 * i, 3, "%02x", tag[i]);
    EXPECT_EQ(std::string(hex), v["tag_hex"].get<std::string>());
  }
}

TEST(ClientCodec, BuildsGoldenRequests) {
  for (const auto& r : vectors()["requests"]) {
    const auto key = rgbd_control::parse_key_hex(r["key_hex"].get<std::string>());
    ASSERT_TRUE(key);
    rgbd_control::ControlCommand c;
    c.seq = r["seq"];
    c.arm = r["arm"] == 1;
    c.roll_us = r["roll"];
    c.pitch_us = r["pitch"];
    c.thr_us = r["thr"];
    c.yaw_us = r["yaw"];
    const auto line = rgbd_control::build_control_request(*key, c);
    ASSERT_TRUE(line);
    EXPECT_EQ(*line, r["line"].get<std::string>());
    EXPECT_LE(line->size(), rgbd_control::kMaxRequestBytes);
  }
}

TEST(ClientCodec, RefusesOutOfRange) {
  const auto key = *rgbd_control::parse_key_hex(vectors()["key_hex"].get<std::string>());
  for (const auto& r : vectors()["invalid_requests"]) {
    rgbd_control::ControlCommand c;
    c.seq = r["seq"];
    c.arm = r["arm"] == 1;
    c.roll_us = r["roll"];
    c.pitch_us = r["pitch"];
    c.thr_us = r["thr"];
    c.yaw_us = r["yaw"];
    std::string err;
    EXPECT_FALSE(rgbd_control::build_control_request(key, c, &err)) << r.dump();
    EXPECT_FALSE(err.empty());
  }
}

TEST(ClientCodec, ParsesGoldenReplies) {
  for (const auto& rep : vectors()["replies"]) {
    std::string err;
    const auto p = rgbd_control::parse_reply(rep["line"].get<std::string>(), &err);
    if (!rep["valid"].get<bool>()) {
      EXPECT_FALSE(p) << rep["line"];
      EXPECT_FALSE(err.empty());
      if (rep.contains("error_mentions")) {
        EXPECT_NE(err.find(rep["error_mentions"].get<std::string>()), std::string::npos) << err;
      }
      continue;
    }
    ASSERT_TRUE(p) << err;
    const auto& f = rep["fields"];
    EXPECT_EQ(p->status, f["status"].get<int>());
    EXPECT_EQ(p->ver, f["ver"].get<int>());
    EXPECT_EQ(p->err, f["err"].get<std::string>());
    EXPECT_EQ(p->state, f["state"].get<std::string>());
    EXPECT_EQ(p->seq, f["seq"].get<uint32_t>());
    EXPECT_EQ(p->clamped, f["clamped"].get<int>());
    for (int i = 0; i < 4; ++i) EXPECT_EQ(p->out_us[i], f["out_us"][i].get<int>());
    for (int i = 0; i < 3; ++i) EXPECT_EQ(p->att_mrad[i], f["att_mrad"][i].get<int>());
    for (int i = 0; i < 6; ++i) EXPECT_EQ(p->imu_raw[i], f["imu_raw"][i].get<int>());
    EXPECT_EQ(p->att_age_ms.has_value(), !f["att_age_ms"].is_null());
    if (p->att_age_ms) {
      EXPECT_EQ(*p->att_age_ms, f["att_age_ms"].get<uint32_t>());
    }
    EXPECT_EQ(p->imu_age_ms.has_value(), !f["imu_age_ms"].is_null());
  }
}

TEST(ClientCodec, EveryTruncationOfAValidReplyIsRejected) {
  const std::string line = vectors()["replies"][0]["line"];
  for (size_t n = 0; n + 1 < line.size(); ++n) {
    EXPECT_FALSE(rgbd_control::parse_reply(line.substr(0, n))) << n;
  }
}

TEST(ClientCodec, ConstantsMatchSpec) {
  const json spec = load(RGBD_CONTROL_SPEC);
  for (const auto& f : spec["control_fields"]) {
    if (f["name"] == "seq" || f["name"] == "arm") continue;
    EXPECT_EQ(f["range"][0].get<int>(), rgbd_control::kChannelMinUs);
    EXPECT_EQ(f["range"][1].get<int>(), rgbd_control::kChannelMaxUs);
  }
  EXPECT_EQ(spec["serial_link"]["max_request_bytes"].get<size_t>(), rgbd_control::kMaxRequestBytes);
  EXPECT_EQ(spec["version"].get<int>(), rgbd_control::kControlLinkVersion);
}

TEST(ClientCodec, KeyHexAndSequenceCounter) {
  EXPECT_FALSE(rgbd_control::parse_key_hex("00"));
  EXPECT_FALSE(rgbd_control::parse_key_hex(std::string(31, '0') + "g"));
  EXPECT_TRUE(rgbd_control::parse_key_hex(std::string(32, 'A')));
  rgbd_control::SequenceCounter c(UINT32_MAX - 1);
  EXPECT_EQ(c.next(), UINT32_MAX);
  EXPECT_FALSE(c.next());
}

}  // namespace
