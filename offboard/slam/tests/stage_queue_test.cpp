// StageQueue: the hand-over between SLAM threads (newest-wins, wait-for-room, idle tracking).
#include "slam/core/stage_queue.hpp"

#include <gtest/gtest.h>

#include <thread>
#include <vector>

namespace rgbdquad::slam {
namespace {

TEST(StageQueue, GivenAFullQueueWhenANewerItemIsPushedReplacingThenTheOlderIsDroppedAndCounted) {
  StageQueue<int> q(1);
  EXPECT_EQ(q.push_replacing(1), 0u);
  EXPECT_EQ(q.push_replacing(2), 1u);
  EXPECT_EQ(q.push_replacing(3), 1u);
  q.close();
  std::vector<int> got;
  drain_stage_queue(q, [&](int v) { got.push_back(v); });
  EXPECT_EQ(got, std::vector<int>{3});
}

TEST(StageQueue, GivenWaitForRoomThenEveryItemArrivesInOrder) {
  StageQueue<int> q(1);
  std::vector<int> got;
  std::thread consumer([&] { drain_stage_queue(q, [&](int v) { got.push_back(v); }); });
  for (int i = 0; i < 100; ++i) q.push_waiting(i);
  q.close();
  consumer.join();
  ASSERT_EQ(got.size(), 100u);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(got[static_cast<std::size_t>(i)], i);
}

TEST(StageQueue, GivenAnItemInWorkThenTheQueueIsNotIdleUntilDone) {
  StageQueue<int> q(1);
  q.push(7);
  q.push(8);  // push() ignores the capacity (its caller bounds the queue)
  EXPECT_EQ(q.load(), 2u);
  EXPECT_TRUE(q.has_waiting());
  const auto item = q.pop();
  ASSERT_TRUE(item.has_value());
  EXPECT_EQ(*item, 7);
  EXPECT_EQ(q.load(), 2u);  // one queued, one in work
  (void)q.pop();
  EXPECT_FALSE(q.has_waiting());
  EXPECT_EQ(q.load(), 2u);
  q.done();
  q.done();
  EXPECT_EQ(q.load(), 0u);
  q.wait_idle();  // returns at once
}

TEST(StageQueue, GivenAClosedEmptyQueueThenPopEndsTheConsumer) {
  StageQueue<int> q(2);
  q.close();
  EXPECT_FALSE(q.pop().has_value());
}

}  // namespace
}  // namespace rgbdquad::slam
