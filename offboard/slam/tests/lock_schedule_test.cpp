// LockSchedule: the record's format, and a replay that holds threads to the recorded order.
#include "slam/core/lock_schedule.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace rgbdquad::slam {
namespace {

std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          (name + "-" + std::to_string(::getpid()) + ".txt"))
      .string();
}

std::string read_all(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// One party's thread: `turns` lock turns, each appending its letter to `order` under the lock.
void take_turns(LockSchedule* s, std::mutex* map, MapParty who, int turns, std::string* order) {
  for (int i = 0; i < turns; ++i) {
    s->before_lock(who);
    std::lock_guard<std::mutex> held(*map);
    s->after_lock(who);
    order->push_back(party_letter(who));
  }
}

TEST(LockSchedule, RecordsRunsOfTurnsAndAnswersInTheOrderTheyHappened) {
  // GIVEN a recorder
  const std::string path = temp_path("lock-schedule-record");
  std::string err;
  auto s = LockSchedule::recorder(path, &err);
  ASSERT_TRUE(s) << err;
  // WHEN tracking takes the map twice, is answered 2, mapping takes it once and is answered 1
  std::mutex map;
  std::string order;
  take_turns(s.get(), &map, MapParty::kTracking, 2, &order);
  EXPECT_EQ(s->answer(MapParty::kTracking, 2), 2);
  take_turns(s.get(), &map, MapParty::kMapping, 1, &order);
  EXPECT_EQ(s->answer(MapParty::kMapping, 1), 1);
  s->flush();
  // THEN the file holds exactly that, and reads back as a replay of 3 turns
  const std::string text = read_all(path);
  EXPECT_NE(text.find("L t 2\nA t 2\nL m 1\nA m 1\n"), std::string::npos) << text;
  auto replay = LockSchedule::replayer(path, &err);
  ASSERT_TRUE(replay) << err;
  EXPECT_EQ(replay->status().turns_in_file, 3u);
  std::filesystem::remove(path);
}

TEST(LockSchedule, ReplayLetsEachThreadTakeTheMapOnlyInItsRecordedTurn) {
  // GIVEN a record of interleaved turns, and both threads ready to take all theirs at once
  std::string err;
  auto s = LockSchedule::replayer_from_text("L m 1\nL t 2\nL m 2\nL t 1\nL m 1\n", &err);
  ASSERT_TRUE(s) << err;
  std::mutex map;
  std::string order;
  // WHEN mapping starts first (unscheduled it would take its four turns before tracking starts)
  std::thread mapping(take_turns, s.get(), &map, MapParty::kMapping, 4, &order);
  std::thread tracking(take_turns, s.get(), &map, MapParty::kTracking, 3, &order);
  mapping.join();
  tracking.join();
  // THEN the turns came in the recorded order, and the replay followed the record to its end
  EXPECT_EQ(order, "mttmmtm");
  const auto st = s->status();
  EXPECT_EQ(st.turns, 7u);
  EXPECT_FALSE(st.left_record) << st.why_free;
}

TEST(LockSchedule, ReplayGivesTheRecordedAnswersNotTheLiveOnes) {
  std::string err;
  auto s = LockSchedule::replayer_from_text("L t 1\nA t 2\nA m 1\nA t 0\n", &err);
  ASSERT_TRUE(s) << err;
  // Each party reads its own answers in order, whatever the other took meanwhile.
  EXPECT_EQ(s->answer(MapParty::kMapping, 0), 1);
  EXPECT_EQ(s->answer(MapParty::kTracking, 5), 2);
  EXPECT_EQ(s->answer(MapParty::kTracking, 5), 0);
  // With the record's answers used up the replay has left the record: live answers, and it says so.
  EXPECT_EQ(s->answer(MapParty::kTracking, 5), 5);
  EXPECT_EQ(s->answer(MapParty::kMapping, 7), 7);
  EXPECT_NE(s->describe().find("no more answers for t"), std::string::npos) << s->describe();
}

TEST(LockSchedule, AThreadWaitingForAFinishedThreadsTurnRunsFreeAndTheReplaySaysSo) {
  // GIVEN a record whose next turn is tracking's, and tracking has finished
  std::string err;
  auto s = LockSchedule::replayer_from_text("L t 1\nL m 1\n", &err);
  ASSERT_TRUE(s) << err;
  s->retire(MapParty::kTracking);
  // WHEN mapping asks for the map
  std::mutex map;
  std::string order;
  take_turns(s.get(), &map, MapParty::kMapping, 1, &order);
  // THEN it gets it (no wait for a turn that never comes) and the status names why
  EXPECT_EQ(order, "m");
  const auto st = s->status();
  EXPECT_TRUE(st.left_record);
  EXPECT_NE(st.why_free.find("t's, whose thread has finished"), std::string::npos) << st.why_free;
}

TEST(LockSchedule, AFrameMissingFromTheReplayIsCaughtWhereTheTurnsWouldStillLineUp) {
  // GIVEN a record of three frames, one turn each
  const std::string path = temp_path("lock-schedule-frames");
  std::string err;
  {
    auto rec = LockSchedule::recorder(path, &err);
    ASSERT_TRUE(rec) << err;
    std::mutex map;
    std::string order;
    for (double stamp : {10.0, 10.033333, 10.066667}) {
      rec->frame(stamp);
      take_turns(rec.get(), &map, MapParty::kTracking, 1, &order);
    }
    EXPECT_EQ(rec->status().frames, 3u);
  }
  // WHEN the same frames replay, and when the second is missing from the replay
  auto same = LockSchedule::replayer(path, &err);
  ASSERT_TRUE(same) << err;
  for (double stamp : {10.0, 10.033333, 10.066667}) same->frame(stamp);
  auto gap = LockSchedule::replayer(path, &err);
  ASSERT_TRUE(gap) << err;
  gap->frame(10.0);
  gap->frame(10.066667);
  std::filesystem::remove(path);
  // THEN the first follows the record; the second leaves it at that frame and says so, though
  // its tracker would have taken the same turn
  EXPECT_FALSE(same->status().left_record) << same->describe();
  EXPECT_EQ(same->status().frames, 3u);
  const auto st = gap->status();
  EXPECT_TRUE(st.left_record);
  EXPECT_NE(st.why_free.find("frame 1 is stamped 10066667 us, the record's 10033333 us"),
            std::string::npos)
      << st.why_free;
}

TEST(LockSchedule, AMalformedLineIsRefusedByNumberButACutLastLineEndsTheRecord) {
  std::string err;
  EXPECT_FALSE(LockSchedule::replayer_from_text("# header\nL t 1\nL x 1\nL m 1\n", &err));
  EXPECT_NE(err.find("line 3"), std::string::npos) << err;
  EXPECT_FALSE(LockSchedule::replayer_from_text("L t 0\nL m 1\n", &err));  // a run of none
  EXPECT_FALSE(LockSchedule::replayer("/nonexistent/lock_schedule.txt", &err));
  EXPECT_NE(err.find("cannot read"), std::string::npos) << err;
  // A killed recorder's file ends mid-line: the record is the lines before it.
  auto s = LockSchedule::replayer_from_text("L t 3\nA t 1\nL m", &err);
  ASSERT_TRUE(s) << err;
  EXPECT_EQ(s->status().turns_in_file, 3u);
}

}  // namespace
}  // namespace rgbdquad::slam
