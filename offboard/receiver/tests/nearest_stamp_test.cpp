// The nearest-timestamp search (nearest_stamp.h) that pairs RGB with depth and matches firmware
// replies to frames: table-driven, GIVEN/WHEN/THEN.
#include "rgbdquad/receiver/nearest_stamp.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <deque>

namespace rgbdquad::receiver {
namespace {

TEST(NearestStamp, GivenStampsWhenSearchedThenTheNearestComesBackAndTiesGoToTheFirst) {
  const std::deque<std::int64_t> stamps_us = {1000, 21000, 41000, 35000};  // arrival order
  const auto stamp = [](std::int64_t t) { return t; };
  struct Row {
    std::int64_t t_us;
    std::int64_t expected_us;
  };
  const Row table[] = {{0, 1000},      {11000, 1000},  // ties (11000, 38000): the first in order
                       {12000, 21000}, {38000, 41000}, {37999, 35000},
                       {-5000, 1000},  {100000, 41000}};
  for (const Row& row : table) {
    const auto it = nearest_stamp(stamps_us.begin(), stamps_us.end(), row.t_us, stamp);
    ASSERT_NE(it, stamps_us.end());
    EXPECT_EQ(*it, row.expected_us) << "t " << row.t_us;
  }
}

TEST(NearestStamp, GivenNoStampWhenSearchedThenTheEndComesBack) {
  const std::deque<std::int64_t> none;
  EXPECT_EQ(nearest_stamp(none.begin(), none.end(), 5, [](std::int64_t t) { return t; }),
            none.end());
}

}  // namespace
}  // namespace rgbdquad::receiver
