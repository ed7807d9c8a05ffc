// Replays protocol/control/vectors/control_vectors.json through the firmware core: SipHash vectors,
// every malformed-request class, and the scenarios (arming, clamping, failsafe timeline to the
// millisecond, replay/forgery rejection, framing). The same file is replayed by the Python and C++
// ground-station codecs.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "controller.h"
#include "imu_cache.h"
#include "line_assembler.h"
#include "rgbd_control/siphash24.h"

namespace {

using nlohmann::json;

const json& vectors() {
  static const json v = [] {
    std::ifstream f(FW_CONTROL_VECTORS);
    if (!f) throw std::runtime_error("cannot open " FW_CONTROL_VECTORS);
    return json::parse(f);
  }();
  return v;
}

std::vector<uint8_t> from_hex(const std::string& h) {
  std::vector<uint8_t> out;
  for (size_t i = 0; i + 1 < h.size(); i += 2)
    out.push_back(static_cast<uint8_t>(std::stoi(h.substr(i, 2), nullptr, 16)));
  return out;
}

std::string to_hex(const uint8_t* p, size_t n) {
  static const char* d = "0123456789abcdef";
  std::string s;
  for (size_t i = 0; i < n; ++i) {
    s += d[p[i] >> 4];
    s += d[p[i] & 15];
  }
  return s;
}

// Latin-1 code points of the JSON strings are the bytes on the wire.
std::string wire_bytes(const std::string& utf8) {
  std::string out;
  for (size_t i = 0; i < utf8.size(); ++i) {
    const auto c = static_cast<unsigned char>(utf8[i]);
    if (c >= 0xC0 && c < 0xE0 && i + 1 < utf8.size()) {
      out +=
          static_cast<char>(((c & 0x1F) << 6) | (static_cast<unsigned char>(utf8[i + 1]) & 0x3F));
      ++i;
    } else {
      out += static_cast<char>(c);
    }
  }
  return out;
}

int reply_status(const char* reply) { return std::atoi(reply); }

TEST(ControlVectors, SipHashMatchesAllVectors) {
  for (const auto& v : vectors()["siphash"]) {
    const auto key = from_hex(v["key_hex"]);
    const auto msg = from_hex(v["msg_hex"]);
    uint8_t tag[8];
    rgbd_control::siphash24_tag_bytes(rgbd_control::siphash24(key.data(), msg.data(), msg.size()),
                                      tag);
    EXPECT_EQ(to_hex(tag, 8), v["tag_hex"].get<std::string>()) << "message length " << msg.size();
  }
}

TEST(ControlVectors, ValidRequestsAreAccepted) {
  const auto key = from_hex(vectors()["key_hex"]);
  for (const auto& r : vectors()["requests"]) {
    // GIVEN a fresh controller, WHEN the golden request arrives, THEN it is applied.
    fw::Controller c(key.data());
    fw::ImuCache imu;
    char reply[fw::kReplyBufferBytes];
    const std::string line = r["line"];
    c.handle_line(line.data(), line.size(), 0, imu, reply, sizeof(reply));
    EXPECT_EQ(reply_status(reply), r["arm"] == 1 && r["thr"].get<int>() > 1100 ? 403 : 200) << line;
  }
}

TEST(ControlVectors, EveryMalformedClassIsRejectedWithoutEffect) {
  const auto key = from_hex(vectors()["key_hex"]);
  for (const auto& m : vectors()["malformed"]) {
    fw::Controller c(key.data());
    fw::ImuCache imu;
    char reply[fw::kReplyBufferBytes];
    const std::string line = wire_bytes(m["line"]);
    c.handle_line(line.data(), line.size(), 0, imu, reply, sizeof(reply));
    EXPECT_EQ(reply_status(reply), m["status"].get<int>()) << m["name"];
    EXPECT_EQ(c.state(), fw::ArmState::kDisarmed) << m["name"];
    EXPECT_EQ(c.last_seq(), 0u) << m["name"];
  }
}

class ScenarioTest : public ::testing::TestWithParam<std::string> {};

TEST_P(ScenarioTest, Replays) {
  const json* scenario = nullptr;
  for (const auto& s : vectors()["scenarios"]) {
    if (s["name"] == GetParam()) scenario = &s;
  }
  ASSERT_NE(scenario, nullptr);
  const auto key = from_hex(vectors()["key_hex"]);
  fw::Controller c((*scenario)["key"].is_null() ? nullptr : key.data());
  fw::LineAssembler assembler;
  fw::ImuCache imu;
  for (const auto& st : (*scenario)["steps"]) {
    const uint32_t t = st["t_ms"];
    const std::string send = wire_bytes(st["send"]);
    std::vector<int> statuses;
    char reply[fw::kReplyBufferBytes];
    for (char b : send) {
      const fw::LineEvent ev = assembler.feed(static_cast<uint8_t>(b), t);
      if (ev == fw::LineEvent::kLine) {
        c.handle_line(assembler.line(), assembler.length(), t, imu, reply, sizeof(reply));
        statuses.push_back(reply_status(reply));
      } else if (ev == fw::LineEvent::kTooLong) {
        c.reply_error(fw::Status::kTooLong, t, imu, reply, sizeof(reply));
        statuses.push_back(reply_status(reply));
      }
    }
    if (assembler.poll(t) == fw::LineEvent::kStalled) {
      c.reply_error(fw::Status::kStalled, t, imu, reply, sizeof(reply));
      statuses.push_back(reply_status(reply));
    }
    c.update(t);
    const std::string where = GetParam() + " @" + std::to_string(t) + " ms";
    if (st["status"].is_null()) {
      EXPECT_TRUE(statuses.empty()) << where;
    } else {
      ASSERT_EQ(statuses.size(), 1u) << where;
      EXPECT_EQ(statuses[0], st["status"].get<int>()) << where;
    }
    EXPECT_EQ(fw::arm_state_name(c.state()), st["state"].get<std::string>()) << where;
    if (st.contains("out_us")) {
      uint16_t out[4];
      c.outputs_us(out);
      for (int ch = 0; ch < 4; ++ch)
        EXPECT_EQ(out[ch], st["out_us"][ch].get<int>()) << where << " ch" << ch + 1;
    }
    if (st.contains("clamped")) {
      EXPECT_EQ(c.clamped_mask(), st["clamped"].get<int>()) << where;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Golden, ScenarioTest,
                         ::testing::Values("arm_clamp_disarm", "arm_refused_throttle_high",
                                           "failsafe_timeline", "rejected_do_not_feed_timer",
                                           "out_of_range", "framing", "no_key"));

TEST(ControlVectors, EveryScenarioIsCovered) {
  EXPECT_EQ(vectors()["scenarios"].size(), 7u) << "add new scenarios to INSTANTIATE_TEST_SUITE_P";
}

}  // namespace
