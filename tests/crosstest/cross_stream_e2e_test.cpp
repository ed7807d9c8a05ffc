// A cross-built rgbd-streamer (ARM, under qemu-user) streams the shipped TUM excerpt to the x86
// StreamReceiver over loopback; every frame the receiver holds must equal, bit for bit, the TUM
// frame with the same capture timestamp as decoded on this host. Lossless depth encodings and raw
// RGB, so any byte-order, alignment or codec difference between the architectures fails here.
// The streamer command comes from $RGBD_STREAMER_CMD (scripts/onboard-arm.sh sets it); the process
// is stopped by its PID.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "rgbdquad/capture/tum_replay_source.h"
#include "rgbdquad/net/socket.h"
#include "rgbdquad/protocol/stream_auth_testing.hpp"
#include "rgbdquad/receiver/stream_receiver.h"
#include "test_support.h"

namespace rgbdquad {
namespace {

namespace fs = std::filesystem;
constexpr const char* kDesk = RGBD_TEST_DATA_DIR "/fr1_desk_9frames";
// qemu runs the streamer ~10-50x slower than native; 9 frame pairs at the original 30 Hz timing
// plus start-up and the 3 s linger stay well inside this.
constexpr int kRunTimeoutMs = 90000;
// At least this many distinct frames per stream must arrive and be checked (of 9): the receiver
// keeps only the newest, and the streamer sends only the newest frame per credit.
constexpr std::size_t kMinFramesChecked = 3;

struct Reference {
  std::map<std::int64_t, std::vector<std::uint8_t>> rgb;  // by capture timestamp (us)
  std::map<std::int64_t, std::vector<std::uint16_t>> depth;
};

Reference load_reference() {
  capture::ManualClock clock;
  capture::TumReplayOptions o;
  o.directory = kDesk;
  o.fps = -1;
  capture::TumReplaySource source(o, &clock);
  Reference ref;
  while (auto frame = source.next()) {
    if (auto* r = std::get_if<capture::RgbFrame>(&*frame))
      ref.rgb[r->capture_timestamp_us] = r->rgb;
    else {
      auto& d = std::get<capture::DepthFrame>(*frame);
      ref.depth[d.capture_timestamp_us] = d.depth;
    }
  }
  return ref;
}

std::vector<std::string> split_words(const std::string& s) {
  std::istringstream in(s);
  std::vector<std::string> words;
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

// Writes the test stream key (mode 0600, as the streamer demands) into a fresh temp folder.
fs::path make_key_dir() {
  char tmpl[] = "/tmp/rgbd_cross_e2e_XXXXXX";
  if (mkdtemp(tmpl) == nullptr) return {};
  const fs::path dir(tmpl);
  {
    std::ofstream key(dir / "stream.key");
    for (std::uint8_t b : protocol::testing::kTestStreamKey)
      key << "0123456789abcdef"[b >> 4] << "0123456789abcdef"[b & 15];
    key << "\n";
  }
  fs::permissions(dir / "stream.key", fs::perms::owner_read | fs::perms::owner_write,
                  fs::perm_options::replace);
  return dir;
}

// Starts $RGBD_STREAMER_CMD + TUM replay options + `extra` towards the given ports; returns the
// PID.
pid_t start_streamer(const fs::path& key_dir, std::uint16_t rgb_port, std::uint16_t depth_port,
                     const std::vector<std::string>& extra) {
  const char* cmd = std::getenv("RGBD_STREAMER_CMD");
  if (cmd == nullptr) return -1;
  std::vector<std::string> args = split_words(cmd);
  for (std::string a :
       {"--source", "tum", "--tum-dir", kDesk, "--host", "127.0.0.1", "--rgb-encoding", "raw",
        "--stats-period", "0", "--log-level", "error", "--config", "/dev/null"}) {
    args.push_back(a);
  }
  for (const std::string& a :
       {std::string("--rgb-port"), std::to_string(rgb_port), std::string("--depth-port"),
        std::to_string(depth_port), std::string("--stream-key-file"),
        (key_dir / "stream.key").string()}) {
    args.push_back(a);
  }
  args.insert(args.end(), extra.begin(), extra.end());
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    execvp(argv[0], argv.data());
    _exit(127);
  }
  return pid;
}

class CrossStreamEndToEnd : public ::testing::TestWithParam<const char*> {};

TEST_P(CrossStreamEndToEnd, TumFramesArriveBitExact) {
  ASSERT_NE(std::getenv("RGBD_STREAMER_CMD"), nullptr)
      << "set RGBD_STREAMER_CMD (scripts/onboard-arm.sh does)";
  const Reference ref = load_reference();
  ASSERT_EQ(ref.depth.size(), 9u);

  const fs::path dir = make_key_dir();
  ASSERT_FALSE(dir.empty());
  receiver::ReceiverOptions options;
  options.key = protocol::testing::kTestStreamKey;
  options.rgb_port = 0;
  options.depth_port = 0;
  receiver::StreamReceiver rx(options, testing::steady_now_us(), nullptr);
  const pid_t pid = start_streamer(dir, rx.rgb_port(), rx.depth_port(),
                                   {"--tum-fps", "0", "--tum-loop", "false", "--depth-encoding",
                                    GetParam(), "--exit-linger-ms", "3000"});
  ASSERT_GT(pid, 0);

  // Check every frame the receiver holds while the streamer runs (newest only, so poll).
  std::set<std::uint32_t> rgb_seen, depth_seen;
  int rgb_mismatch = 0, depth_mismatch = 0, unknown_timestamp = 0;
  int status = 0;
  const bool exited = testing::eventually(
      [&] {
        if (auto d = rx.newest_depth(); d && depth_seen.insert(d->info.sequence).second) {
          auto it = ref.depth.find(d->info.capture_timestamp_us);
          if (it == ref.depth.end())
            ++unknown_timestamp;
          else if (it->second != d->depth)
            ++depth_mismatch;
        }
        if (auto r = rx.newest_rgb(); r && rgb_seen.insert(r->info.sequence).second) {
          auto it = ref.rgb.find(r->info.capture_timestamp_us);
          if (it == ref.rgb.end())
            ++unknown_timestamp;
          else if (it->second != r->rgb)
            ++rgb_mismatch;
        }
        return waitpid(pid, &status, WNOHANG) == pid;
      },
      kRunTimeoutMs);
  if (!exited) {
    kill(pid, SIGTERM);
    waitpid(pid, &status, 0);
  }
  fs::remove_all(dir);
  EXPECT_TRUE(exited) << "streamer did not finish the 9-frame replay in " << kRunTimeoutMs << " ms";
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "streamer exit status " << status;
  const auto c = rx.counters();
  EXPECT_EQ(c.depth.crc_errors + c.rgb.crc_errors + c.depth.invalid_frames + c.rgb.invalid_frames +
                c.depth.protocol_errors + c.rgb.protocol_errors + c.depth.handshakes_refused +
                c.rgb.handshakes_refused,
            0u);
  EXPECT_GE(depth_seen.size(), kMinFramesChecked);
  EXPECT_GE(rgb_seen.size(), kMinFramesChecked);
  EXPECT_EQ(depth_mismatch, 0);
  EXPECT_EQ(rgb_mismatch, 0);
  EXPECT_EQ(unknown_timestamp, 0);
  std::printf(
      "cross e2e (%s depth, raw rgb): %zu depth + %zu rgb frames checked bit-exact of 9 each "
      "(receiver got %llu + %llu)\n",
      GetParam(), depth_seen.size() - static_cast<std::size_t>(depth_mismatch),
      rgb_seen.size() - static_cast<std::size_t>(rgb_mismatch),
      static_cast<unsigned long long>(c.depth.frames),
      static_cast<unsigned long long>(c.rgb.frames));
}

// The golden and hostile vectors of protocol/vectors (the same bytes protocol_tests decodes on
// both architectures) that a ground station could send to a streamer: every vector whose expected
// decoding (manifest.json) holds only errors or the receiver-to-streamer messages (StreamChallenge,
// HandshakeAck, FrameRequest). A fake ground station answers each streamer connection with the
// next vector (vectors alternate between the two streams; the streamer's capped 1 s reconnect
// backoff sets the pace). The streamer must drop each bad connection and reconnect, never crash or
// stop, and end cleanly on SIGTERM.
std::vector<std::vector<std::uint8_t>> streamer_side_vectors() {
  std::ifstream manifest_file(std::string(RGBD_PROTOCOL_VECTORS_DIR) + "/manifest.json");
  const auto manifest = nlohmann::json::parse(manifest_file);
  const std::set<std::string> to_streamer = {"StreamChallenge", "HandshakeAck", "FrameRequest"};
  std::vector<std::vector<std::uint8_t>> vectors;
  for (const auto& v : manifest.at("vectors")) {
    bool relevant = true;
    for (const auto& e : v.at("expected").at("events")) {
      if (e.value("event", "") == "message" &&
          !to_streamer.count(e.at("message").at("type").get<std::string>())) {
        relevant = false;
      }
    }
    if (!relevant) continue;
    std::ifstream in(std::string(RGBD_PROTOCOL_VECTORS_DIR) + "/" + v.at("file").get<std::string>(),
                     std::ios::binary);
    vectors.emplace_back((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }
  return vectors;
}

TEST(CrossStreamHostile, ProtocolVectorsFromTheGroundStationLeaveTheStreamerRunning) {
  ASSERT_NE(std::getenv("RGBD_STREAMER_CMD"), nullptr)
      << "set RGBD_STREAMER_CMD (scripts/onboard-arm.sh does)";
  const auto vectors = streamer_side_vectors();
  ASSERT_GE(vectors.size(), 20u);
  net::Waker waker;
  net::UniqueFd listeners[2] = {net::listen_tcp("127.0.0.1", 0), net::listen_tcp("127.0.0.1", 0)};
  const fs::path dir = make_key_dir();
  ASSERT_FALSE(dir.empty());
  const pid_t pid =
      start_streamer(dir, net::local_port(listeners[0]), net::local_port(listeners[1]),
                     {"--tum-fps", "0", "--tum-loop", "true"});
  ASSERT_GT(pid, 0);
  // Per connection: read what the streamer sends first (bounded), answer with the next vector,
  // close.
  std::size_t next = 0, served[2] = {0, 0};
  int status = 0;
  bool died = false;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(kRunTimeoutMs);
  while (next < vectors.size() && std::chrono::steady_clock::now() < deadline) {
    if (waitpid(pid, &status, WNOHANG) == pid) {
      died = true;
      break;
    }
    for (int s = 0; s < 2; ++s) {
      if (next == vectors.size() ||
          net::wait_readable(listeners[s].get(), waker, 20) != net::IoStatus::kOk)
        continue;
      auto conn = net::accept_tcp(listeners[s], nullptr);
      if (!conn) continue;
      std::uint8_t buffer[4096];
      std::size_t got = 0;
      (void)net::read_some(conn->get(), buffer, sizeof buffer, &got, waker, 200);
      const auto& v = vectors[next++];
      ++served[s];
      (void)net::send_all(conn->get(), v.data(), v.size(), waker, 1000);
    }
  }
  const bool alive = !died && waitpid(pid, &status, WNOHANG) == 0;
  if (alive) {
    kill(pid, SIGTERM);
    waitpid(pid, &status, 0);
  }
  fs::remove_all(dir);
  EXPECT_TRUE(alive) << "streamer ended during the hostile replay, status " << status;
  EXPECT_EQ(next, vectors.size()) << "not every vector was delivered before the deadline";
  EXPECT_GT(served[0], 0u);
  EXPECT_GT(served[1], 0u);
  EXPECT_TRUE(alive && WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << "exit status after SIGTERM " << status;
  std::printf(
      "cross hostile: %zu protocol vectors answered to the streamer's connections; streamer alive, "
      "clean exit on SIGTERM: %s\n",
      next, alive && WIFEXITED(status) && WEXITSTATUS(status) == 0 ? "yes" : "no");
}

INSTANTIATE_TEST_SUITE_P(LosslessDepth, CrossStreamEndToEnd,
                         ::testing::Values("rvl", "zstd-delta"));

}  // namespace
}  // namespace rgbdquad
