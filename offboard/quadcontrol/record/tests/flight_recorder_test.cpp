// FlightRecorder: events reach the file (counted), a write error stops recording with one logged
// line while the callers go on, rotation and the run's budget. The files' content is validated by
// the Python `mcap` reader (offboard/recorder/tests/).
#include "record/flight_recorder.hpp"

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "tests/options_problem.hpp"

namespace rgbdquad::quadcontrol {
namespace {
namespace fs = std::filesystem;

fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() /
                     ("flight_recorder_test_" + std::to_string(::getpid()) + "_" + name);
  fs::remove_all(d);
  return d;
}
RecorderOptions options_in(const fs::path& dir) {
  RecorderOptions o;
  o.enabled = true;
  o.dir = dir.string();
  o.image_every_n_frames = 1;
  o.flush_period_ms = 50;
  return o;
}
cv::Mat noise_rgb(int seed) {
  cv::Mat m(480, 640, CV_8UC3);
  cv::theRNG().state = static_cast<std::uint64_t>(seed);
  cv::randu(m, 0, 255);
  return m;
}

TEST(FlightRecorder, GivenEventsWhenClosedThenEveryOneIsWrittenAndCounted) {
  const fs::path dir = fresh_dir("basic");
  std::vector<std::string> log;
  std::string error;
  auto o = options_in(dir);
  o.queue_max_frames = 100;  // this test must not drop
  auto r = FlightRecorder::open(
      o, "flight", [&log](const std::string& l) { log.push_back(l); }, &error);
  ASSERT_TRUE(r) << error;
  const cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(5000));
  for (int i = 0; i < 5; ++i) {
    r->frame(i, 1000 * i, 1000 * i + 10, 1.0, 30.0, noise_rgb(i), depth, slam::Intrinsics{});
    PoseRecord p;
    p.sequence = i;
    p.tracking = i > 0;
    r->pose(p);
    CommandRecord c;
    c.seq = i;
    c.send_us = 1000 * i + 20;
    c.pose_capture_us = 1000 * i;
    c.pose_us = 1000 * i + 15;
    r->command(c);
    r->status(1000 * i, i < 2 ? "disarmed" : "armed", "x");
  }
  const RecorderStats live = r->stats();
  ASSERT_TRUE(live.capture_to_command_ms.has_value());
  EXPECT_DOUBLE_EQ(*live.capture_to_command_ms, 0.02);
  EXPECT_DOUBLE_EQ(*live.pose_to_command_ms, 0.005);
  r.reset();
  ASSERT_TRUE(log.empty()) << log.front();
  ASSERT_TRUE(fs::exists(dir / "flight-000.mcap"));
  EXPECT_GT(fs::file_size(dir / "flight-000.mcap"),
            5u * 150000u);  // five noise JPEGs (~220 kB each at q90)
}

TEST(FlightRecorder, GivenAFileSizeLimitWhenReachedThenRecordingStopsWithOneLineAndCallersGoOn) {
  const fs::path dir = fresh_dir("full");
  std::vector<std::string> log;
  std::string error;
  auto r = FlightRecorder::open(
      options_in(dir), "flight", [&log](const std::string& l) { log.push_back(l); }, &error);
  ASSERT_TRUE(r) << error;
  rlimit old{};
  getrlimit(RLIMIT_FSIZE, &old);
  auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  rlimit lim{200000, old.rlim_max};  // below one depth image
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &lim), 0);
  const cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(5000));
  for (int i = 0; i < 40 && !r->stats().failed; ++i) {
    r->frame(i, i, i, 0.0, 30.0, noise_rgb(i), depth, slam::Intrinsics{});
    usleep(20000);
  }
  for (int i = 0; i < 50 && !r->stats().failed; ++i) usleep(20000);
  for (int i = 0; i < 10; ++i) r->command(CommandRecord{});  // after the failure: dropped, counted
  const RecorderStats s = r->stats();
  r.reset();
  setrlimit(RLIMIT_FSIZE, &old);
  std::signal(SIGXFSZ, old_handler);
  ASSERT_TRUE(s.failed);
  EXPECT_NE(s.error.find("File too large"), std::string::npos) << s.error;
  EXPECT_GE(s.dropped_after_failure, 10u);
  ASSERT_EQ(log.size(), 1u);
  EXPECT_NE(log[0].find("recording stopped"), std::string::npos);
}

TEST(FlightRecorder, GivenASmallFileLimitThenFilesRotateAndTheBudgetDeletesTheOldest) {
  const fs::path dir = fresh_dir("rotate");
  std::vector<std::string> log;
  std::string error;
  auto o = options_in(dir);
  o.max_file_mb = 1.0;
  o.max_total_mb = 2.5;
  o.zstd = false;  // sizes predictable: ~0.3 MB of base64 noise JPEG per frame
  o.queue_max_frames = 100;
  auto r = FlightRecorder::open(
      o, "flight", [&log](const std::string& l) { log.push_back(l); }, &error);
  ASSERT_TRUE(r) << error;
  const cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(5000));
  for (int i = 0; i < 16; ++i)
    r->frame(i, i, i, 0.0, 30.0, noise_rgb(i), depth, slam::Intrinsics{});
  r.reset();
  std::uint64_t total = 0;
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    total += fs::file_size(e.path());
    ++files;
  }
  EXPECT_FALSE(fs::exists(dir / "flight-000.mcap"));  // the oldest went first
  EXPECT_GE(files, 2);
  EXPECT_LE(static_cast<double>(total),
            (2.5 + 1.0) * 1024 * 1024);  // budget + the file being written
  bool rotated = false, deleted = false;
  for (const auto& l : log) {
    rotated |= l.find("rotated to") != std::string::npos;
    deleted |= l.find("deleted") != std::string::npos;
  }
  EXPECT_TRUE(rotated);
  EXPECT_TRUE(deleted);
}

TEST(FlightRecorder, GivenTheLinksPayloadsThenTheyAreStoredAsTheyAreWithoutEncoding) {
  const fs::path dir = fresh_dir("payloads");
  std::string error;
  auto o = options_in(dir);
  o.zstd = false;  // the file then holds the base64 text as written
  o.depth_preview_every_n_frames = 0;
  auto r = FlightRecorder::open(
      o, "flight", [](const std::string&) {}, &error);
  ASSERT_TRUE(r) << error;
  // Distinct marker bytes stand for the link's JPEG and RVL payloads.
  const auto jpeg = std::make_shared<const std::vector<std::uint8_t>>(3000, std::uint8_t{0xAB});
  const auto rvl = std::make_shared<const std::vector<std::uint8_t>>(3000, std::uint8_t{0xCD});
  for (int i = 0; i < 3; ++i) {
    r->frame(i, i, i, 0.0, 30.0, noise_rgb(i), cv::Mat(480, 640, CV_16UC1, cv::Scalar(0)),
             slam::Intrinsics{}, EncodedImage{"jpeg", jpeg}, EncodedImage{"rvl", rvl});
  }
  const RecorderStats s = r->stats();
  r.reset();
  std::ifstream in(dir / "flight-000.mcap", std::ios::binary);
  const std::string file((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto count = [&file](const std::string& needle) {
    std::size_t n = 0;
    for (auto at = file.find(needle); at != std::string::npos; at = file.find(needle, at + 1)) ++n;
    return n;
  };
  EXPECT_EQ(count(base64_encode(jpeg->data(), jpeg->size())), 3u);
  EXPECT_EQ(count(base64_encode(rvl->data(), rvl->size())), 3u);
  EXPECT_EQ(count("\"encoding\":\"rvl\""), 3u);
  EXPECT_EQ(s.images_dropped, 0u);
}

TEST(FlightRecorder, GivenAQueueByteBoundThenImagesBeyondItAreDroppedAndCountedTelemetryKept) {
  const fs::path dir = fresh_dir("bytes");
  std::string error;
  auto o = options_in(dir);
  o.queue_max_mb = 4.0;       // under three frames of pixels the writer must encode (1.5 MB each)
  o.queue_max_frames = 1000;  // the byte bound is the one that acts
  auto r = FlightRecorder::open(
      o, "flight", [](const std::string&) {}, &error);
  ASSERT_TRUE(r) << error;
  const cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(5000));
  const cv::Mat rgb = noise_rgb(1);
  constexpr int kFrames = 200;  // far faster than JPEG-encoding them: the queue fills
  for (int i = 0; i < kFrames; ++i) r->frame(i, i, i, 0.0, 30.0, rgb, depth, slam::Intrinsics{});
  const RecorderStats live = r->stats();
  r.reset();
  EXPECT_LE(static_cast<double>(live.queued_bytes_peak), 4.0 * 1024 * 1024);
  EXPECT_GT(live.images_dropped, 0u);
  EXPECT_EQ(live.dropped_queue_full, 0u);  // every frame's telemetry went in
}

TEST(RecorderOptions, GivenBadValuesThenValidateSaysWhich) {
  RecorderOptions o;
  EXPECT_EQ(testing::problem(o), "");  // disabled: nothing to check
  o.enabled = true;
  EXPECT_NE(testing::problem(o).find("dir"), std::string::npos);
  o.dir = "/tmp/x";
  EXPECT_EQ(testing::problem(o), "");
  o.flush_period_ms = 20000;
  EXPECT_NE(testing::problem(o).find("flush_period_ms"), std::string::npos);
}

TEST(Base64, GivenRfc4648VectorsThenEncodesThem) {
  EXPECT_EQ(base64_encode(std::string("")), "");
  EXPECT_EQ(base64_encode(std::string("f")), "Zg==");
  EXPECT_EQ(base64_encode(std::string("fo")), "Zm8=");
  EXPECT_EQ(base64_encode(std::string("foo")), "Zm9v");
  EXPECT_EQ(base64_encode(std::string("foobar")), "Zm9vYmFy");
}
}  // namespace
}  // namespace rgbdquad::quadcontrol
