// fakenect replay through the real libfreenect API, end to end: a fakenect dump is written from
// the shipped TUM frames (raw 11-bit disparity + RGB, as fakenect-record stores them), the real
// rgbd-streamer binary runs under Debian's `fakenect` wrapper (which swaps in libfreenect's
// fakenect build), and the in-process StreamReceiver must get depth and RGB bit-exact with what
// the dump encodes.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "rgbdquad/camera/tum_cameras.hpp"
#include "rgbdquad/capture/freenect_source.h"
#include "rgbdquad/protocol/stream_auth_testing.hpp"
#include "rgbdquad/receiver/stream_receiver.h"
#include "test_support.h"

namespace rgbdquad {
namespace {

namespace fs = std::filesystem;
constexpr const char* kDesk = RGBD_TEST_DATA_DIR "/fr1_desk_9frames";
constexpr std::uint16_t kNoReading = 2047;

// Inverse of FreenectSource::disparity_to_mm (Magnenat's fit), as a Kinect would have measured.
std::uint16_t mm_to_disparity(double mm) {
  if (mm <= 0) return kNoReading;
  const double raw = std::round((std::atan(mm / 1000.0 / 0.1236) - 1.1863) * 2842.5);
  return raw >= 0 && raw < kNoReading ? static_cast<std::uint16_t>(raw) : kNoReading;
}

struct Dump {
  std::vector<std::vector<std::uint16_t>> depth_mm;  // what the streamer must send
  std::vector<std::vector<std::uint8_t>> rgb;
};

// Writes INDEX.txt + d-*.pgm / r-*.ppm. fakenect copies the bytes after the PGM header verbatim
// into the depth buffer (like fakenect-record wrote them from it), so samples are host order.
Dump write_dump(const fs::path& dir) {
  Dump dump;
  std::ifstream rgb_list(std::string(kDesk) + "/rgb.txt");
  std::ifstream depth_list(std::string(kDesk) + "/depth.txt");
  std::vector<std::pair<double, std::string>> rgb_files, depth_files;
  std::string line;
  while (std::getline(rgb_list, line)) {
    if (line.empty() || line[0] == '#') continue;
    double t;
    char name[256];
    if (std::sscanf(line.c_str(), "%lf %255s", &t, name) == 2) rgb_files.push_back({t, name});
  }
  while (std::getline(depth_list, line)) {
    if (line.empty() || line[0] == '#') continue;
    double t;
    char name[256];
    if (std::sscanf(line.c_str(), "%lf %255s", &t, name) == 2) depth_files.push_back({t, name});
  }
  std::ofstream index(dir / "INDEX.txt");
  const double t0 = std::min(rgb_files[0].first, depth_files[0].first);
  for (std::size_t i = 0; i < std::min(rgb_files.size(), depth_files.size()); ++i) {
    cv::Mat d = cv::imread(std::string(kDesk) + "/" + depth_files[i].second, cv::IMREAD_UNCHANGED);
    std::vector<std::uint16_t> raw(640 * 480), mm(640 * 480);
    for (int k = 0; k < 640 * 480; ++k) {
      raw[k] = mm_to_disparity(d.at<std::uint16_t>(k) * 1000.0 / camera::kTumDepthUnitsPerM);
      mm[k] = capture::FreenectSource::disparity_to_mm(raw[k]);
    }
    char name[128];
    std::snprintf(name, sizeof name, "d-%.6f-%u-%zu.pgm", depth_files[i].first - t0,
                  static_cast<unsigned>(i * 2000000), i);
    {
      std::ofstream f(dir / name, std::ios::binary);
      f << "P5 640 480 65535\n";
      f.write(reinterpret_cast<const char*>(raw.data()), raw.size() * 2);
    }
    index << name << "\n";
    cv::Mat bgr = cv::imread(std::string(kDesk) + "/" + rgb_files[i].second, cv::IMREAD_COLOR);
    cv::Mat rgb;
    cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
    std::snprintf(name, sizeof name, "r-%.6f-%u-%zu.ppm", rgb_files[i].first - t0,
                  static_cast<unsigned>(i * 2000000 + 1000), i);
    {
      std::ofstream f(dir / name, std::ios::binary);
      f << "P6 640 480 255\n";
      f.write(reinterpret_cast<const char*>(rgb.data), 640 * 480 * 3);
    }
    index << name << "\n";
    dump.depth_mm.push_back(std::move(mm));
    dump.rgb.emplace_back(rgb.data, rgb.data + 640 * 480 * 3);
  }
  return dump;
}

TEST(FakenectEndToEnd, DumpReplaysThroughLibfreenectIntoTheReceiverBitExact) {
  if (access("/usr/bin/fakenect", X_OK) != 0)
    GTEST_SKIP() << "libfreenect-bin (fakenect) not installed";
  char tmpl[] = "/tmp/rgbd_fakenect_XXXXXX";
  ASSERT_NE(mkdtemp(tmpl), nullptr);
  const fs::path dir(tmpl);
  const Dump dump = write_dump(dir);
  ASSERT_EQ(dump.depth_mm.size(), 9u);
  // Registration identity: the dump's depth was made in the RGB camera's view.
  {
    std::ofstream config(dir / "streamer.yaml");
    const camera::TumCamera& k = camera::kTumRosDefault;  // both cameras: the Kinect default model
    const std::string model = "[" + std::to_string(k.fx_px) + ", " + std::to_string(k.fy_px) +
                              ", " + std::to_string(k.cx_px) + ", " + std::to_string(k.cy_px) +
                              "]\n";
    config << "depth_intrinsics: " << model << "rgb_intrinsics: " << model
           << "t_rgb_depth_m: [0, 0, 0]\n"
              "stats_period_s: 0\nlog_level: warn\nexit_linger_ms: 3000\n"
           << "stream_key_file: " << (dir / "stream.key").string() << "\n";
  }
  // The stream key both ends hold (mode 0600, as the streamer demands).
  {
    std::ofstream key(dir / "stream.key");
    for (std::uint8_t b : protocol::testing::kTestStreamKey)
      key << "0123456789abcdef"[b >> 4] << "0123456789abcdef"[b & 15];
    key << "\n";
  }
  fs::permissions(dir / "stream.key", fs::perms::owner_read | fs::perms::owner_write,
                  fs::perm_options::replace);
  receiver::ReceiverOptions options;
  options.key = protocol::testing::kTestStreamKey;
  options.bind_address = "127.0.0.1";
  options.rgb_port = 0;
  options.depth_port = 0;
  receiver::StreamReceiver rx(options, testing::steady_now_us(), nullptr);

  const std::string rgb_port = std::to_string(rx.rgb_port());
  const std::string depth_port = std::to_string(rx.depth_port());
  const std::string config = (dir / "streamer.yaml").string();
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    execl("/usr/bin/fakenect", "fakenect", dir.c_str(), RGBD_STREAMER_BIN, "-c", config.c_str(),
          "--source", "freenect", "--freenect-disparity-depth", "--host", "127.0.0.1", "--rgb-port",
          rgb_port.c_str(), "--depth-port", depth_port.c_str(), "--depth-encoding", "rvl",
          "--rgb-encoding", "raw", static_cast<char*>(nullptr));
    _exit(127);
  }
  // The dump spans 0.3 s; wait for the streamer to finish it (and linger) or time out.
  int status = 0;
  const bool exited =
      testing::eventually([&] { return waitpid(pid, &status, WNOHANG) == pid; }, 20000);
  if (!exited) {
    kill(pid, SIGTERM);
    waitpid(pid, &status, 0);
  }
  EXPECT_TRUE(exited) << "rgbd-streamer did not finish the dump";

  const auto c = rx.counters();
  EXPECT_GE(c.depth.frames, 1u);
  EXPECT_GE(c.rgb.frames, 1u);
  EXPECT_EQ(c.depth.crc_errors + c.rgb.crc_errors + c.depth.invalid_frames + c.rgb.invalid_frames,
            0u);
  const auto depth = rx.newest_depth();
  const auto rgb = rx.newest_rgb();
  ASSERT_TRUE(depth && rgb);
  // THEN the newest depth is one of the dump's frames, bit for bit after disparity -> mm
  bool depth_match = false, rgb_match = false;
  for (const auto& d : dump.depth_mm) depth_match = depth_match || d == depth->depth;
  for (const auto& r : dump.rgb) rgb_match = rgb_match || r == rgb->rgb;
  EXPECT_TRUE(depth_match) << "received depth differs from every dump frame";
  EXPECT_TRUE(rgb_match) << "received RGB differs from every dump frame";
  EXPECT_EQ(depth->units_per_m, 1000.0);
  EXPECT_TRUE(rx.newest_pair().has_value());
  std::printf("fakenect e2e: %llu depth, %llu rgb frames received of 9 each\n",
              static_cast<unsigned long long>(c.depth.frames),
              static_cast<unsigned long long>(c.rgb.frames));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rgbdquad
