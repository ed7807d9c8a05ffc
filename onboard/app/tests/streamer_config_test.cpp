// Config: the shipped file parses to the built-in defaults; overrides apply; bad files and values
// are rejected with messages naming the key.
#include "rgbdquad/app/streamer_config.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>

namespace rgbdquad::app {
namespace {

std::string write_temp(const std::string& text) {
  char name[] = "/tmp/rgbd_streamer_config_XXXXXX";
  const int fd = mkstemp(name);
  EXPECT_GE(fd, 0);
  std::ofstream(name) << text;
  close(fd);
  return name;
}

TEST(StreamerConfig, ShippedFileEqualsDefaultsAndIsValid) {
  StreamerConfig loaded;
  load_yaml_file(RGBD_SHIPPED_CONFIG, &loaded);
  EXPECT_EQ(loaded.to_string(), StreamerConfig{}.to_string())
      << "onboard/config/rgbd-streamer.yaml must document the built-in defaults";
  std::string error;
  EXPECT_TRUE(loaded.is_valid(&error)) << error;
}

TEST(StreamerConfig, FileValuesOverrideDefaults) {
  const auto path = write_temp(
      "source: tum\ntum_directory: /data/x\ndepth_encoding: zstd-delta\n"
      "rgb_intrinsics: [517.3, 516.5, 318.6, 255.3]\nrgb_port: 7000\n");
  StreamerConfig c;
  load_yaml_file(path, &c);
  std::remove(path.c_str());
  EXPECT_EQ(c.source, "tum");
  EXPECT_EQ(c.depth_encoding, "zstd-delta");
  EXPECT_DOUBLE_EQ(c.rgb_intrinsics[0], 517.3);
  EXPECT_EQ(c.rgb_port, 7000);
  EXPECT_EQ(c.depth_port, 5601);
  std::string error;
  EXPECT_TRUE(c.is_valid(&error)) << error;
}

TEST(StreamerConfig, BadFilesNameTheProblem) {
  struct Case {
    const char* text;
    const char* expected_in_message;
  };
  const Case cases[] = {
      {"sorce: tum\n", "unknown key 'sorce'"},
      {"rgb_port: seventy\n", "rgb_port"},
      {"rgb_intrinsics: [1, 2, 3]\n", "rgb_intrinsics"},
      {"[1, 2]\n", "mapping"},
      {"host: [unclosed\n", "config"},
  };
  for (const auto& c : cases) {
    const auto path = write_temp(c.text);
    StreamerConfig config;
    try {
      load_yaml_file(path, &config);
      ADD_FAILURE() << "accepted: " << c.text;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(c.expected_in_message), std::string::npos) << e.what();
    }
    std::remove(path.c_str());
  }
  StreamerConfig missing;
  EXPECT_THROW(load_yaml_file("/nonexistent/rgbd.yaml", &missing), std::runtime_error);
}

TEST(StreamerConfig, InvalidValuesAreRejected) {
  std::vector<std::pair<const char*, std::function<void(StreamerConfig*)>>> cases = {
      {"source", [](StreamerConfig* c) { c->source = "webcam"; }},
      {"tum without directory", [](StreamerConfig* c) { c->source = "tum"; }},
      {"same ports", [](StreamerConfig* c) { c->depth_port = c->rgb_port; }},
      {"depth encoding", [](StreamerConfig* c) { c->depth_encoding = "png"; }},
      {"rgb encoding", [](StreamerConfig* c) { c->rgb_encoding = "rvl"; }},
      {"jpeg quality", [](StreamerConfig* c) { c->jpeg_quality = 0; }},
      {"nan intrinsics", [](StreamerConfig* c) { c->rgb_intrinsics[0] = std::nan(""); }},
      {"log level", [](StreamerConfig* c) { c->log_level = "loud"; }},
  };
  for (const auto& [name, mutate] : cases) {
    StreamerConfig c;
    mutate(&c);
    std::string error;
    EXPECT_FALSE(c.is_valid(&error)) << name;
    EXPECT_FALSE(error.empty()) << name;
  }
}

}  // namespace
}  // namespace rgbdquad::app
