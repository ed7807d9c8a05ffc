// slam-server's socket-free core with time passed in: sessions outlive connections for a grace
// period and are resumed or taken over by id; a connection closes, with a cause, on every deadline
// (no hello, idle, a message begun and not finished - also when dripped -, replies not taken) and
// on protocol faults. Deterministic: no sockets, no clock.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "rgbdquad/protocol/codec.hpp"
#include "slam/map/map_io.hpp"
#include "slam_connection.hpp"
#include "slam_sessions.hpp"

namespace rgbdquad::slamlink {
namespace {

namespace proto = rgbdquad::protocol;

SessionRegistry make_registry(std::int64_t grace_ms = 1000, std::size_t max_sessions = 2) {
  SessionRegistryOptions o;
  o.resume_grace_ms = grace_ms;
  o.max_sessions = max_sessions;
  return SessionRegistry(o, [](const SessionStart&) {
    return std::make_unique<SlamLinkSession>(slam::PipelineOptions{});
  });
}

std::vector<std::uint8_t> hello_bytes(std::uint64_t session_id,
                                      std::uint64_t schema_hash = proto::kSchemaHash) {
  proto::SlamHello h;
  h.schema_hash = schema_hash;
  h.peer_name = "test";
  h.session_id = session_id;
  return proto::encode(h).bytes;
}

std::vector<proto::Message> decode_all(const std::vector<std::uint8_t>& bytes) {
  proto::StreamDecoder d;
  d.feed(bytes);
  std::vector<proto::Message> out;
  for (auto r = d.next(); r.status != proto::DecodeStatus::kNeedMoreBytes; r = d.next())
    if (r.message) out.push_back(*r.message);
  return out;
}

TEST(SessionRegistry, GivenAParkedSessionWhenTheSameIdComesBackWithinTheGraceThenItIsResumed) {
  SessionRegistry reg = make_registry(1000);
  std::vector<std::string> log;
  AttachResult a = reg.attach(42, 1, 0, &log);
  ASSERT_NE(a.session, nullptr);
  EXPECT_FALSE(a.resumed);
  reg.detach(1, 100);
  EXPECT_TRUE(reg.expire(1099).empty());
  AttachResult b = reg.attach(42, 2, 1099, &log);
  EXPECT_TRUE(b.resumed);
  EXPECT_EQ(b.session, a.session);
  EXPECT_FALSE(b.displaced_connection.has_value());
  ASSERT_EQ(log.size(), 2u);
  EXPECT_EQ(log.front(), "map 000000000000002a started (new)");
  EXPECT_EQ(log.back().rfind("map 000000000000002a resumed (world frame kept, ", 0), 0u)
      << log.back();
  EXPECT_NE(log.back().find("parked 999 ms)"), std::string::npos) << log.back();
}

TEST(SessionRegistry, GivenACheckpointOfTheAskedIdThenARestartedServerResumesItElseStartsANewMap) {
  // GIVEN a checkpoint folder holding a whole map file for session id 42 and garbage for session id
  // 43
  const std::filesystem::path dir = ::testing::TempDir() + "/registry_checkpoints";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  SessionRegistryOptions o;
  o.resume_grace_ms = 1000;
  o.checkpoint_dir = dir.string();
  std::vector<SessionStart> starts;
  SessionRegistry reg(
      o,
      [&starts](const SessionStart& s) {
        starts.push_back(s);
        return std::make_unique<SlamLinkSession>(slam::PipelineOptions{});
      },
      [](const std::string& path, std::string* why) { return slam::check_map_file(path, why); });
  std::string err;
  slam::FeatureOptions orb;
  orb.kind = slam::DetectorKind::kOrb;
  ASSERT_TRUE(save_map(reg.checkpoint_path(42), slam::SlamMap{},
                       slam::MapFileContext{slam::CameraModel{}, orb}, &err, 3))
      << err;
  { std::ofstream(reg.checkpoint_path(43)) << "half a map"; }
  std::vector<std::string> log;
  // WHEN session id 42 is asked for: THEN it resumes from the checkpoint (map and world frame kept)
  const AttachResult a = reg.attach(42, 1, 0, &log);
  EXPECT_TRUE(a.resumed);
  ASSERT_EQ(starts.size(), 1u);
  EXPECT_TRUE(starts[0].resume_from_checkpoint);
  EXPECT_EQ(starts[0].checkpoint_path, (dir / "map-000000000000002a.map").string());
  EXPECT_EQ(log.back().rfind("map 000000000000002a resumed from its checkpoint", 0), 0u)
      << log.back();
  // AND session id 43's broken checkpoint starts a new map, saying why
  EXPECT_FALSE(reg.attach(43, 2, 0, &log).resumed);
  EXPECT_FALSE(starts[1].resume_from_checkpoint);
  EXPECT_NE(log.back().find("checkpoint is unusable"), std::string::npos) << log.back();
  // AND a session the registry names itself (id 0) is never checkpointed: its id restarts; a
  // client's id that shares bits with the registry's prefix is
  const AttachResult own = reg.attach(0, 3, 0, &log);
  EXPECT_FALSE(own.resumed);
  EXPECT_TRUE(starts[2].checkpoint_path.empty());
  EXPECT_FALSE(reg.checkpoint_path(0x7ff75fbefab44523ull).empty());
  // AND a session that ends for good deletes its checkpoint; slam-server stopping keeps them
  reg.detach(1, 0);
  ASSERT_EQ(reg.expire(1000).size(), 1u);
  EXPECT_FALSE(std::filesystem::exists(reg.checkpoint_path(42)));
  const auto stopped = reg.finish_all();
  EXPECT_TRUE(std::filesystem::exists(reg.checkpoint_path(43)));
}

TEST(SessionRegistry, GivenAParkedSessionWhenTheGraceEndsThenItIsFinishedAndTheIdStartsANewMap) {
  SessionRegistry reg = make_registry(1000);
  reg.attach(42, 1, 0, nullptr);
  reg.detach(1, 100);
  ASSERT_EQ(*reg.next_expiry_ms(), 1100);
  const auto ended = reg.expire(1100);
  ASSERT_EQ(ended.size(), 1u);
  EXPECT_NE(ended[0].find("no client for 1000 ms"), std::string::npos);
  EXPECT_FALSE(reg.attach(42, 2, 1200, nullptr).resumed);
}

TEST(SessionRegistry, GivenAnAttachedSessionWhenANewConnectionPresentsItsIdThenItTakesItOver) {
  SessionRegistry reg = make_registry();
  reg.attach(7, 1, 0, nullptr);
  AttachResult b = reg.attach(7, 2, 10, nullptr);
  EXPECT_TRUE(b.resumed);
  ASSERT_TRUE(b.displaced_connection.has_value());
  EXPECT_EQ(*b.displaced_connection, 1);
  EXPECT_EQ(reg.session_of(1), nullptr);
  EXPECT_EQ(reg.session_of(2), b.session);
}

TEST(SessionRegistry, GivenAFullRegistryThenTheOldestParkedMapMakesRoomElseANewcomerIsRefused) {
  SessionRegistry reg = make_registry(100000, 2);
  reg.attach(1, 1, 0, nullptr);
  reg.attach(2, 2, 0, nullptr);
  AttachResult refused = reg.attach(3, 3, 10, nullptr);
  EXPECT_EQ(refused.session, nullptr);
  EXPECT_NE(refused.refusal.find("busy"), std::string::npos);
  reg.detach(1, 20);
  std::vector<std::string> log;
  AttachResult c = reg.attach(3, 3, 30, &log);
  ASSERT_NE(c.session, nullptr);
  EXPECT_NE(log.front().find("dropped to make room"), std::string::npos);
  EXPECT_EQ(reg.size(), 2u);
}

TEST(SessionRegistry, GivenIdZeroThenTheRegistryNamesTheSession) {
  SessionRegistry reg = make_registry();
  const AttachResult a = reg.attach(0, 1, 0, nullptr);
  const AttachResult b = reg.attach(0, 2, 0, nullptr);
  EXPECT_NE(a.session_id, 0u);
  EXPECT_NE(a.session_id, b.session_id);
}

struct Step {
  std::int64_t now_ms;
  std::vector<std::uint8_t> bytes;
};

struct TimeoutCase {
  const char* name;
  std::vector<Step> steps;  // fed in order, process() after each
  std::int64_t check_ms;    // timed_out() asked at this time
  const char* cause;        // expected substring; "" = still open
};

class ConnectionDeadlines : public ::testing::TestWithParam<TimeoutCase> {};

TEST_P(ConnectionDeadlines, GivenAPeerWhenItsDeadlinePassesThenTheConnectionClosesWithTheCause) {
  ConnectionOptions o;
  o.hello_timeout_ms = 500;
  o.idle_timeout_ms = 5000;
  o.message_timeout_ms = 1000;
  o.write_timeout_ms = 1000;
  SessionRegistry reg = make_registry();
  SlamConnection c(1, "peer", o, 0);
  for (const Step& s : GetParam().steps) {
    c.on_bytes(s.bytes.data(), s.bytes.size(), s.now_ms);
    std::vector<int> displaced;
    bool flush_first = false;
    ASSERT_FALSE(c.process(reg, s.now_ms, &displaced, nullptr, &flush_first));
    c.consumed_output(c.output().size(), s.now_ms);  // the peer reads every reply
    ASSERT_FALSE(c.timed_out(s.now_ms)) << "closed too early at " << s.now_ms;
  }
  const auto cause = c.timed_out(GetParam().check_ms);
  if (std::string(GetParam().cause).empty()) {
    EXPECT_FALSE(cause) << *cause;
  } else {
    ASSERT_TRUE(cause);
    EXPECT_NE(cause->find(GetParam().cause), std::string::npos) << *cause;
    EXPECT_LE(c.next_deadline_ms(), GetParam().check_ms);
  }
}

std::vector<Step> drip(std::int64_t from_ms, std::int64_t every_ms, std::size_t bytes) {
  std::vector<Step> steps;
  const auto frame = proto::encode(proto::SlamHello{}).bytes;  // any message: 10 of its bytes
  for (std::size_t i = 0; i < bytes; ++i)
    steps.push_back({from_ms + static_cast<std::int64_t>(i) * every_ms, {frame[i % frame.size()]}});
  return steps;
}

std::vector<TimeoutCase> timeout_cases() {
  std::vector<TimeoutCase> cases;
  cases.push_back({"silent", {}, 500, "no SlamHello within 500 ms"});
  cases.push_back({"hello_in_time_then_quiet", {{100, hello_bytes(9)}}, 4000, ""});
  cases.push_back({"idle", {{100, hello_bytes(9)}}, 5100, "idle: no bytes for 5000 ms"});
  auto half = hello_bytes(9);
  half.resize(half.size() / 2);
  cases.push_back({"stops_mid_message",
                   {{100, hello_bytes(9)}, {200, half}},
                   1200,
                   "begun and not finished within 1000 ms"});
  auto dripping = drip(200, 100, 10);  // a byte every 100 ms: the idle timer alone would never fire
  dripping.insert(dripping.begin(), Step{100, hello_bytes(9)});
  cases.push_back({"dripping", dripping, 1200, "begun and not finished"});
  return cases;
}

INSTANTIATE_TEST_SUITE_P(SlamConnection, ConnectionDeadlines, ::testing::ValuesIn(timeout_cases()),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(SlamConnection, GivenAHelloThenTheReplyNamesTheSessionAndLaterTheResume) {
  SessionRegistry reg = make_registry();
  SlamConnection a(1, "peer", ConnectionOptions{}, 0);
  const auto h = hello_bytes(0xABC);
  a.on_bytes(h.data(), h.size(), 0);
  std::vector<int> displaced;
  bool flush_first = false;
  ASSERT_FALSE(a.process(reg, 0, &displaced, nullptr, &flush_first));
  auto replies = decode_all(a.output());
  ASSERT_EQ(replies.size(), 1u);
  const auto& r1 = std::get<proto::SlamHello>(replies[0]);
  EXPECT_EQ(r1.session_id, 0xABCu);
  EXPECT_FALSE(r1.resumed);
  EXPECT_TRUE(r1.refusal.empty());
  SlamConnection b(2, "peer", ConnectionOptions{}, 10);
  b.on_bytes(h.data(), h.size(), 10);
  ASSERT_FALSE(b.process(reg, 10, &displaced, nullptr, &flush_first));
  const auto& r2 = std::get<proto::SlamHello>(decode_all(b.output()).at(0));
  EXPECT_TRUE(r2.resumed);
  ASSERT_EQ(displaced.size(), 1u);
  EXPECT_EQ(displaced[0], 1);
}

TEST(SlamConnection, GivenProtocolFaultsThenTheCauseIsGiven) {
  struct Case {
    const char* name;
    std::vector<std::uint8_t> bytes;
    const char* cause;
  };
  proto::RgbdFrame frame;
  frame.rgb.header.pixel_format = proto::PixelFormat::kRgb8;
  frame.depth.header.pixel_format = proto::PixelFormat::kDepth16;
  frame.rgb.header.width = frame.depth.header.width = 1;
  frame.rgb.header.height = frame.depth.header.height = 1;
  frame.rgb.payload.resize(3);
  frame.depth.payload.resize(2);
  frame.rgb.header.payload_length = 3;
  frame.depth.header.payload_length = 2;
  const auto frame_bytes = proto::encode(frame);
  ASSERT_TRUE(frame_bytes.ok()) << frame_bytes.error;
  const std::vector<Case> cases = {
      {"frame before hello", frame_bytes.bytes, "RgbdFrame before SlamHello"},
      {"incompatible hello", hello_bytes(1, proto::kSchemaHash ^ 1u), "incompatible peer"},
      {"wrong direction", proto::encode(proto::PoseUpdate{}).bytes, "unexpected PoseUpdate"},
  };
  for (const Case& c : cases) {
    SessionRegistry reg = make_registry();
    SlamConnection conn(1, "peer", ConnectionOptions{}, 0);
    conn.on_bytes(c.bytes.data(), c.bytes.size(), 0);
    std::vector<int> displaced;
    bool flush_first = false;
    const auto cause = conn.process(reg, 0, &displaced, nullptr, &flush_first);
    ASSERT_TRUE(cause) << c.name;
    EXPECT_NE(cause->find(c.cause), std::string::npos) << c.name << ": " << *cause;
  }
}

TEST(SlamConnection, GivenGarbageThenItIsSkippedCountedAndLoggedOnce) {
  SessionRegistry reg = make_registry();
  SlamConnection c(1, "peer", ConnectionOptions{}, 0);
  std::vector<std::string> log;
  for (int i = 0; i < 50; ++i) {
    std::vector<std::uint8_t> junk(64, static_cast<std::uint8_t>('R'));  // 'R' starts the magic
    junk.push_back('G');
    junk.push_back('B');
    junk.push_back('Q');
    junk.insert(junk.end(), 12, 0xFF);  // a header whose CRC is wrong
    c.on_bytes(junk.data(), junk.size(), i);
    std::vector<int> displaced;
    bool flush_first = false;
    (void)c.process(reg, i, &displaced, &log, &flush_first);
  }
  EXPECT_LE(log.size(), 1u);
  EXPECT_NE(c.summary().find("undecodable"), std::string::npos) << c.summary();
}

}  // namespace
}  // namespace rgbdquad::slamlink
