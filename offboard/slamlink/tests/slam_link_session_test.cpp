// SLAM-link session on real frames from tests/data, through the real protocol codec: each
// RgbdFrame gets exactly one PoseUpdate for that pair_sequence - LOST with a reason for a frame
// that cannot be used - and every pose put on the wire passes the codec's checks (pose_to_wire).
#include "slam_link_session.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

#include "rgbdquad/camera/tum_cameras.hpp"
#include "rgbdquad/protocol/codec.hpp"
#include "slam/dataset/tum_dataset.hpp"

namespace rgbdquad::slamlink {
namespace {

namespace proto = rgbdquad::protocol;
const std::string kExcerpt = std::string(SLAM_REPO_DIR) + "/tests/data/fr1_xyz_first30";

proto::RgbdFrame to_wire(const slam::RgbdFrame& f, std::uint32_t seq) {
  proto::RgbdFrame m;
  m.pair_sequence = seq;
  const rgbdquad::camera::TumCamera& fr1 = rgbdquad::camera::kTumFr1;
  m.intrinsics = {fr1.fx_px, fr1.fy_px, fr1.cx_px, fr1.cy_px, {0, 0, 0, 0, 0}};
  m.depth_scale_units_per_m = rgbdquad::camera::kTumDepthUnitsPerM;
  auto header = [&](proto::PixelFormat fmt, std::size_t bytes) {
    proto::FrameHeader h;
    h.sequence = seq;
    h.capture_timestamp_us = static_cast<std::uint64_t>(f.stamp_s * 1e6);
    h.width = static_cast<std::uint16_t>(f.rgb.cols);
    h.height = static_cast<std::uint16_t>(f.rgb.rows);
    h.pixel_format = fmt;
    h.payload_length = static_cast<std::uint32_t>(bytes);
    return h;
  };
  const std::size_t n = static_cast<std::size_t>(f.rgb.total());
  m.rgb.payload.resize(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const cv::Vec3b bgr = f.rgb.at<cv::Vec3b>(static_cast<int>(i));
    m.rgb.payload[3 * i] = bgr[2];
    m.rgb.payload[3 * i + 1] = bgr[1];
    m.rgb.payload[3 * i + 2] = bgr[0];
  }
  m.depth.payload.resize(2 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint16_t d = f.depth.at<std::uint16_t>(static_cast<int>(i));
    m.depth.payload[2 * i] = static_cast<std::uint8_t>(d & 0xFF);
    m.depth.payload[2 * i + 1] = static_cast<std::uint8_t>(d >> 8);
  }
  m.rgb.header = header(proto::PixelFormat::kRgb8, m.rgb.payload.size());
  m.depth.header = header(proto::PixelFormat::kDepth16, m.depth.payload.size());
  return m;
}

// Encodes, decodes through the stream decoder (as the server does), and hands to the session.
proto::PoseUpdate roundtrip(SlamLinkSession* s, const proto::RgbdFrame& m, std::string* err) {
  const proto::EncodeResult e = proto::encode(m);
  EXPECT_TRUE(e.ok()) << e.error;
  proto::StreamDecoder dec;
  dec.feed(e.bytes);
  proto::DecodeResult r = dec.next();
  EXPECT_EQ(r.status, proto::DecodeStatus::kMessage) << r.detail;
  const auto* f = r.message ? std::get_if<proto::RgbdFrame>(&*r.message) : nullptr;
  EXPECT_NE(f, nullptr);
  return s->on_frame(f ? *f : m, err);
}

slam::PipelineOptions orb_options() {
  slam::PipelineOptions o;
  o.frontend.features.kind = slam::DetectorKind::kOrb;
  return o;
}

TEST(SlamLinkSession, GivenFramesWhenProcessedThenOnePoseUpdatePerFrame) {
  SlamLinkSession s(orb_options());
  std::string err;
  auto ds = slam::TumDataset::open(kExcerpt, slam::TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  for (std::uint32_t i = 0; i < 5; ++i) {
    auto f = ds->load(i, &err);
    ASSERT_TRUE(f) << err;
    const proto::PoseUpdate u = roundtrip(&s, to_wire(*f, 100 + i), &err);
    EXPECT_TRUE(err.empty()) << err;
    EXPECT_EQ(u.pair_sequence, 100 + i);
    EXPECT_EQ(u.tracking_state,
              i == 0 ? proto::TrackingState::kInitializing : proto::TrackingState::kTracking);
    if (i > 0) {
      EXPECT_GT(u.inlier_count, 50u);
    }
    EXPECT_TRUE(proto::validate(proto::Message{u}).empty());
  }
  EXPECT_EQ(s.frames_processed(), 5u);
  EXPECT_EQ(s.frames_faulted(), 0u);
}

TEST(SlamLinkSession, GivenFramesWithAnImuAttitudeThenTheTrackerPredictsRotationFromIt) {
  slam::PipelineOptions options = orb_options();
  options.backend.kind =
      slam::BackendKind::kLocalMap;  // slam-server's default, the system that flies
  SlamLinkSession s(options);
  std::string err;
  auto ds = slam::TumDataset::open(kExcerpt, slam::TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  // GIVEN frames 0, 1 and 3 with an attitude (fr1_xyz barely rotates: a constant one), 2 without
  for (std::uint32_t i = 0; i < 4; ++i) {
    auto f = ds->load(i, &err);
    ASSERT_TRUE(f) << err;
    proto::RgbdFrame m = to_wire(*f, 100 + i);
    if (i != 2) m.attitude = {true, {0.5, 0.5, 0.5, 0.5}};
    roundtrip(&s, m, &err);
    EXPECT_TRUE(err.empty()) << err;
  }
  // THEN only a frame whose predecessor had one too gets its rotation from the attitude
  for (std::int64_t i = 0; i < 4; ++i) {
    const auto rec = s.pipeline()->record(i);
    ASSERT_TRUE(rec) << i;
    EXPECT_EQ(rec->attitude_predicted, i == 1) << i;
    EXPECT_EQ(rec->state, slam::TrackingState::kTracking)
        << i;  // the first frame is the first keyframe
  }
}

TEST(SlamLinkSession, GivenMapFilesThenASessionSavesItsMapAndTheNextStartsInIt) {
  slam::PipelineOptions o;
  o.frontend.features.kind = slam::DetectorKind::kOrb;
  o.backend.kind = slam::BackendKind::kLocalMap;
  const std::string map_path = ::testing::TempDir() + "/session.map";
  std::string err;
  auto ds = slam::TumDataset::open(kExcerpt, slam::TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  {
    // GIVEN a session that saves its map
    SlamLinkSession first(o, SessionMapFiles{"", map_path, "", "", false});
    for (std::uint32_t i = 0; i < 10; ++i) roundtrip(&first, to_wire(*ds->load(i, &err), i), &err);
    EXPECT_NE(first.finish_summary().find("map saved to"), std::string::npos);
  }
  // WHEN a new session starts from it, on later frames
  SlamLinkSession second(o, SessionMapFiles{map_path, "", "", "", false});
  const proto::PoseUpdate u = roundtrip(&second, to_wire(*ds->load(12, &err), 0), &err);
  // THEN its first frame is tracked in the saved map's world frame (relocalised, not a new map)
  EXPECT_TRUE(err.empty()) << err;
  EXPECT_EQ(u.tracking_state, proto::TrackingState::kTracking);
  EXPECT_EQ(second.pipeline()->summary().relocalisations, 1u);
  // AND a session given a file that is no map says so on its first answer and goes on in a new map
  const std::string junk = ::testing::TempDir() + "/junk.map";
  { std::ofstream(junk) << "not a map"; }
  SlamLinkSession third(o, SessionMapFiles{junk, "", "", "", false});
  roundtrip(&third, to_wire(*ds->load(0, &err), 0), &err);
  EXPECT_NE(err.find("map not loaded"), std::string::npos) << err;
  EXPECT_NE(third.finish_summary().find("bad magic"), std::string::npos);
}

TEST(SlamLinkSession, GivenACheckpointWrittenWhileRunningThenARestartResumesTheSameWorldFrame) {
  slam::PipelineOptions o = orb_options();
  o.backend.kind = slam::BackendKind::kLocalMap;
  o.checkpoint_period_s = 0;  // after every mapped keyframe
  const std::string path = ::testing::TempDir() + "/session-checkpoint.map";
  std::filesystem::remove(path);
  std::string err;
  auto ds = slam::TumDataset::open(kExcerpt, slam::TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  proto::PoseUpdate before;
  {
    // GIVEN a running session that checkpoints its map
    SessionMapFiles files;
    files.checkpoint_path = path;
    SlamLinkSession first(o, files);
    for (std::uint32_t i = 0; i < 10; ++i)
      before = roundtrip(&first, to_wire(*ds->load(i, &err), i), &err);
    ASSERT_EQ(before.tracking_state, proto::TrackingState::kTracking);
    // THEN the checkpoint appears while it runs (written by its checkpoint thread, not at the end)
    for (int k = 0; k < 200 && !std::filesystem::exists(path); ++k)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    ASSERT_TRUE(std::filesystem::exists(path));
    EXPECT_NE(first.finish_summary().find("map checkpoints"), std::string::npos);
  }
  // WHEN a new session resumes it (slam-server restarted) and is sent the last frame again
  SessionMapFiles resume;
  resume.checkpoint_path = path;
  resume.resume_from_checkpoint = true;
  SlamLinkSession second(o, resume);
  const proto::PoseUpdate after = roundtrip(&second, to_wire(*ds->load(9, &err), 0), &err);
  // THEN the frame is relocalised in the checkpointed map, at the pose the first session gave it
  EXPECT_TRUE(err.empty()) << err;
  ASSERT_EQ(after.tracking_state, proto::TrackingState::kTracking);
  EXPECT_EQ(second.pipeline()->summary().relocalisations, 1u);
  for (int a = 0; a < 3; ++a)
    EXPECT_NEAR(after.T_world_cam.t_m[a], before.T_world_cam.t_m[a], 0.01);
  // AND a session told to resume a checkpoint it cannot load answers LOST with the reason, never
  // a new map under a client that was told its world frame is kept
  const std::string junk = ::testing::TempDir() + "/junk-checkpoint.map";
  { std::ofstream(junk) << "not a map"; }
  resume.checkpoint_path = junk;
  SlamLinkSession third(o, resume);
  for (std::uint32_t i = 0; i < 3; ++i) {
    const proto::PoseUpdate u = roundtrip(&third, to_wire(*ds->load(i, &err), i), &err);
    EXPECT_EQ(u.tracking_state, proto::TrackingState::kLost);
    EXPECT_NE(err.find("checkpoint cannot be resumed"), std::string::npos) << err;
  }
}

TEST(SlamLinkSession, GivenATablesFolderThenTheEndedSessionWritesOneFrameRowPerFrameWithItsStages) {
  // GIVEN a session told to write its tables into a folder that does not exist yet
  const std::string dir = ::testing::TempDir() + "/slam_link_tables/session-1";
  std::filesystem::remove_all(dir);
  SlamLinkSession s(orb_options(), SessionMapFiles{"", "", dir, "", false});
  std::string err;
  auto ds = slam::TumDataset::open(kExcerpt, slam::TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  // WHEN it tracks the 30 frames, then 10 more (the first 10 again, at later indices: more than
  // the second of records a session holds, so that the oldest rows are streamed during the flight)
  // and ends
  for (std::uint32_t i = 0; i < 40; ++i) roundtrip(&s, to_wire(*ds->load(i % 30, &err), i), &err);
  const std::string summary = s.finish_summary();
  // THEN it says where the tables went, and frames.csv has its header and one row per frame, in
  // order, the first 30 frames after the first tracked, with their stage times and flags
  EXPECT_NE(summary.find("tables written to " + dir), std::string::npos) << summary;
  std::ifstream in(dir + "/frames.csv");
  ASSERT_TRUE(in) << dir;
  std::string header, line;
  std::getline(in, header);
  EXPECT_NE(header.find("relocalised,features_ms,matching_ms,relocalise_ms,prediction_stale"),
            std::string::npos)
      << header;
  int rows = 0, tracked = 0;
  while (std::getline(in, line)) {
    EXPECT_EQ(line.substr(0, line.find(',')), std::to_string(rows));
    if (rows < 30 && line.find(",tracking,") != std::string::npos) ++tracked;
    ++rows;
  }
  EXPECT_EQ(rows, 40);
  EXPECT_EQ(tracked, 29);  // the first frame initialises the map
  EXPECT_TRUE(std::filesystem::exists(dir + "/mapping.csv"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/loops.csv"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/rss.csv"));  // slam-server samples no RSS
  // AND a folder that cannot be made is reported, not thrown
  SlamLinkSession blocked(orb_options(), SessionMapFiles{"", "", "/proc/no/such/dir", "", false});
  roundtrip(&blocked, to_wire(*ds->load(0, &err), 0), &err);
  EXPECT_NE(blocked.finish_summary().find("tables NOT written"), std::string::npos);
}

TEST(SlamLinkSession, GivenUnusableFramesThenEachStillGetsALostPoseUpdateWithAReason) {
  SlamLinkSession s(slam::PipelineOptions{});
  std::string err;
  auto ds = slam::TumDataset::open(kExcerpt, slam::TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds);
  auto f = ds->load(0, &err);
  ASSERT_TRUE(f);
  const proto::RgbdFrame frame = to_wire(*f, 1);
  struct Case {
    const char* name;
    proto::RgbdFrame frame;
    const char* reason;
  };
  std::vector<Case> cases;
  cases.push_back({"truncated depth", frame, "payload size"});
  cases.back().frame.depth.payload.resize(100);
  cases.push_back({"JPEG", frame, "RAW"});
  cases.back().frame.rgb.header.encoding = proto::Encoding::kRgbJpeg;
  std::uint32_t seq = 7;
  for (Case& c : cases) {
    c.frame.pair_sequence = seq;
    const proto::PoseUpdate u = s.on_frame(c.frame, &err);
    EXPECT_EQ(u.pair_sequence, seq) << c.name;
    EXPECT_EQ(u.tracking_state, proto::TrackingState::kLost) << c.name;
    EXPECT_EQ(u.inlier_count, 0u) << c.name;
    EXPECT_NE(err.find(c.reason), std::string::npos) << c.name << ": " << err;
    EXPECT_TRUE(proto::validate(proto::Message{u}).empty()) << c.name;
    ++seq;
  }
  EXPECT_EQ(s.frames_faulted(), cases.size());
}

// A pipeline whose records are scripted per frame index: what the session puts on the wire is
// compared with what the pipeline said.
class ScriptedPipeline : public SessionPipeline {
 public:
  explicit ScriptedPipeline(std::map<std::int64_t, slam::FrameRecord> script)
      : script_(std::move(script)) {}
  void submit(slam::RgbdFrame) override {}
  std::optional<slam::FrameRecord> record(std::int64_t index) const override {
    const auto it = script_.find(index);
    return it == script_.end() ? std::nullopt : std::optional<slam::FrameRecord>(it->second);
  }
  bool load_map(const std::string&, std::string*) override { return true; }
  bool save_map(const std::string&, std::string*) const override { return true; }
  void finish() override {}
  slam::PipelineSummary summary() const override { return {}; }
  bool start_tables(const std::string&, std::string*) override { return true; }
  bool finish_tables(std::string*) override { return true; }

 private:
  std::map<std::int64_t, slam::FrameRecord> script_;
};

TEST(SlamLinkSession,
     GivenLoopCorrectionsThenEachPoseUpdateDeclaresTheCountItsPoseIsExpressedAfter) {
  // GIVEN a pipeline that tracks frames 0-2 and 4, whose map is corrected before frame 2, and that
  // rejects frame 3
  std::map<std::int64_t, slam::FrameRecord> script;
  for (std::int64_t i = 0; i < 5; ++i) {
    slam::FrameRecord r;
    r.index = i;
    r.ok = i != 3;
    r.error = r.ok ? "" : "scripted rejection";
    r.state = slam::TrackingState::kTracking;
    r.inliers = 80;
    r.map_corrections = i >= 2 ? 1 : 0;
    r.T_world_cam.translation() =
        Eigen::Vector3d(0.1 * static_cast<double>(i), 0, i >= 2 ? 0.7 : 0.0);
    script[i] = r;
  }
  auto factory = [&script](const slam::PipelineOptions&, const slam::Intrinsics&, std::string*) {
    return std::unique_ptr<SessionPipeline>(new ScriptedPipeline(script));
  };
  SlamLinkSession s(orb_options(), {}, factory);
  std::string err;
  auto ds = slam::TumDataset::open(kExcerpt, slam::TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  auto f = ds->load(0, &err);
  ASSERT_TRUE(f) << err;
  // WHEN five frames go through the session and the wire codec
  std::vector<proto::PoseUpdate> updates;
  for (std::uint32_t seq = 1; seq <= 5; ++seq) {
    const proto::RgbdFrame frame = to_wire(*f, seq);
    const proto::PoseUpdate u = s.on_frame(frame, &err);
    const proto::EncodeResult e = proto::encode(proto::Message{u});
    ASSERT_TRUE(e.ok()) << e.error;
    proto::StreamDecoder dec;
    dec.feed(e.bytes);
    const proto::DecodeResult r = dec.next();
    ASSERT_EQ(r.status, proto::DecodeStatus::kMessage) << r.detail;
    updates.push_back(std::get<proto::PoseUpdate>(*r.message));
  }
  // THEN the count changes exactly with the corrected pose, and the rejected frame's LOST answer
  // repeats the last count (a fault is not a map correction)
  const std::vector<std::uint32_t> expected = {0, 0, 1, 1, 1};
  for (std::size_t i = 0; i < updates.size(); ++i) {
    EXPECT_EQ(updates[i].map_correction_count, expected[i]) << "frame " << i + 1;
  }
  EXPECT_EQ(updates[3].tracking_state, proto::TrackingState::kLost);
  EXPECT_EQ(updates[2].tracking_state, proto::TrackingState::kTracking);
  EXPECT_DOUBLE_EQ(updates[2].T_world_cam.t_m[2], 0.7);
}

TEST(SlamLinkSession, GivenAFrameFromAnotherCameraMidSessionThenItIsRefusedWithBothCalibrations) {
  SlamLinkSession s(orb_options());
  std::string err;
  auto ds = slam::TumDataset::open(kExcerpt, slam::TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  // GIVEN a session whose map was started with the fr1 camera
  for (std::uint32_t i = 0; i < 3; ++i) roundtrip(&s, to_wire(*ds->load(i, &err), i), &err);
  ASSERT_TRUE(err.empty()) << err;
  // WHEN frames arrive with another focal length, then another depth scale
  for (const bool depth : {false, true}) {
    proto::RgbdFrame other = to_wire(*ds->load(3, &err), depth ? 11 : 10);
    if (depth) {
      other.depth_scale_units_per_m = 1000.0;
    } else {
      other.intrinsics.fx_px = 525.0;
    }
    const proto::PoseUpdate u = roundtrip(&s, other, &err);
    // THEN each is answered LOST, naming both cameras, and is not put into the map
    EXPECT_EQ(u.tracking_state, proto::TrackingState::kLost);
    EXPECT_NE(err.find("not the one this map is built with"), std::string::npos) << err;
    EXPECT_NE(err.find(depth ? "depth 1000 units/m" : "fx 525"), std::string::npos) << err;
  }
  EXPECT_EQ(s.frames_faulted(), 2u);
  EXPECT_EQ(s.frames_processed(), 3u);
  // AND the session's own camera is still tracked
  const proto::PoseUpdate back = roundtrip(&s, to_wire(*ds->load(4, &err), 12), &err);
  EXPECT_TRUE(err.empty()) << err;
  EXPECT_EQ(back.tracking_state, proto::TrackingState::kTracking);
}

// A rotation matrix orthonormal only to rounding can give |w| = 1 + 2e-16, which the codec's
// range check refuses: before pose_to_wire, slam-server then failed to encode the PoseUpdate and
// closed the connection without a word (the SLAM-link resets once seen in HIL flights).
TEST(PoseToWire, GivenRotationsAtTheEdgeOfTheCodecsChecksThenTheWirePoseIsValid) {
  struct Case {
    const char* name;
    Eigen::Matrix3d R;
  };
  Eigen::Matrix3d scaled_identity = Eigen::Matrix3d::Identity() * (1.0 + 1e-15);
  Eigen::Matrix3d drifted =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix() *
      (1.0 + 5e-6);
  Eigen::Matrix3d half_turn = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix();
  half_turn(1, 1) += 4e-16;
  const std::vector<Case> cases = {{"identity + rounding", scaled_identity},
                                   {"rotation with 5e-6 scale drift", drifted},
                                   {"half turn + rounding", half_turn}};
  for (const Case& c : cases) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = c.R;
    T.translation() = Eigen::Vector3d(0.1, -0.2, 1.7);
    const auto p = pose_to_wire(T);
    ASSERT_TRUE(p) << c.name;
    proto::PoseUpdate u;
    u.T_world_cam = *p;
    EXPECT_TRUE(proto::validate(proto::Message{u}).empty())
        << c.name << ": " << proto::validate(proto::Message{u});
  }
}

TEST(PoseToWire, GivenNoRotationOrNonFiniteValuesThenRefused) {
  Eigen::Isometry3d nan = Eigen::Isometry3d::Identity();
  nan.translation().x() = std::nan("");
  Eigen::Isometry3d scaled = Eigen::Isometry3d::Identity();
  scaled.linear() *= 1.5;
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.translation().z() = 1e9;
  EXPECT_FALSE(pose_to_wire(nan));
  EXPECT_FALSE(pose_to_wire(scaled));
  EXPECT_FALSE(pose_to_wire(far));
}

}  // namespace
}  // namespace rgbdquad::slamlink
