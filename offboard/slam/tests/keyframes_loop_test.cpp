// Keyframe policy decisions, LLC clamp and GLC candidate rotation (table-driven).
#include <gtest/gtest.h>

#include <functional>
#include <map>
#include <utility>
#include <vector>

#include "slam/thesis/glc_search.hpp"
#include "slam/thesis/keyframes.hpp"
#include "slam/thesis/loop.hpp"

namespace rgbdquad::slam {
namespace {

struct KfCase {
  const char* name;
  KeyframePolicy policy;
  std::optional<double> since_s;
  std::optional<KeyframeEvidence> evidence;
  bool expected;
};

TEST(KeyframePolicy, TableOfDecisions) {
  const KfCase cases[] = {
      {"first frame", KeyframePolicy::kRansac, std::nullopt, std::nullopt, true},
      {"no evidence", KeyframePolicy::kRansac, 0.1, std::nullopt, true},
      {"good overlap", KeyframePolicy::kRansac, 0.1, KeyframeEvidence{1000, 400, 300}, false},
      {"matches just under 15 %", KeyframePolicy::kRansac, 0.1, KeyframeEvidence{1000, 149, 149},
       true},
      {"matches at 15 %", KeyframePolicy::kRansac, 0.1, KeyframeEvidence{1000, 150, 150}, false},
      {"inliers under 45 %", KeyframePolicy::kRansac, 0.1, KeyframeEvidence{1000, 400, 179}, true},
      {"inliers at 45 %", KeyframePolicy::kRansac, 0.1, KeyframeEvidence{1000, 400, 180}, false},
      {"fixed: 0.2 s after", KeyframePolicy::kFixedRate, 0.2, KeyframeEvidence{1000, 0, 0}, false},
      {"fixed: 1/3 s after (30 Hz, 10 frames)", KeyframePolicy::kFixedRate, 10 * 0.0333,
       std::nullopt, true},
      {"fixed: first frame", KeyframePolicy::kFixedRate, std::nullopt, std::nullopt, true},
  };
  for (const auto& c : cases) {
    KeyframeOptions o;
    o.policy = c.policy;
    EXPECT_EQ(decide_new_keyframe(o, c.since_s, c.evidence), c.expected) << c.name;
  }
}

Eigen::Isometry3d pose(double x, double yaw_rad) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, 0, 0);
  T.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

TEST(LocalLoopClosure, GivenLargeCorrectionThenClampedTo25PercentOfEdge) {
  // Edge: 4 cm and 0.04 rad. Measurement disagrees by 10 cm and 0.1 rad -> 1 cm / 0.01 rad applied.
  const auto out = clamp_llc_correction(pose(1.0, 0.0), pose(1.1, 0.1), pose(0.04, 0.04), 0.25);
  EXPECT_NEAR(out.translation().x(), 1.01, 1e-12);
  EXPECT_NEAR(Eigen::AngleAxisd(out.rotation()).angle(), 0.01, 1e-9);
}

TEST(LocalLoopClosure, GivenSmallCorrectionThenAppliedFully) {
  const auto out = clamp_llc_correction(pose(1.0, 0.0), pose(1.005, 0.002), pose(0.04, 0.04), 0.25);
  EXPECT_NEAR(out.translation().x(), 1.005, 1e-12);
  EXPECT_NEAR(Eigen::AngleAxisd(out.rotation()).angle(), 0.002, 1e-9);
}

TEST(LocalLoopClosure, GivenStillCameraOrNonFiniteThenPredictionKept) {
  const auto still =
      clamp_llc_correction(pose(1.0, 0.0), pose(1.1, 0.1), Eigen::Isometry3d::Identity(), 0.25);
  EXPECT_TRUE(still.isApprox(pose(1.0, 0.0)));
  Eigen::Isometry3d nan = pose(1.0, 0.0);
  nan.translation().x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(
      clamp_llc_correction(pose(1.0, 0.0), nan, pose(0.04, 0), 0.25).isApprox(pose(1.0, 0.0)));
}

TEST(GlobalLoopClosure, GivenFewOlderKeyframesThenAllTested) {
  EXPECT_EQ(select_glc_candidates(0, 5, 7), std::vector<std::size_t>{});
  EXPECT_EQ(select_glc_candidates(3, 5, 7), (std::vector<std::size_t>{0, 1, 2}));
}

TEST(GlobalLoopClosure, GivenManyKeyframesThenOnePerBlockRotating) {
  // 14 older keyframes, 7 blocks of 2: iteration 0 takes the first of each, 1 the second, 2 wraps.
  EXPECT_EQ(select_glc_candidates(14, 0, 7), (std::vector<std::size_t>{0, 2, 4, 6, 8, 10, 12}));
  EXPECT_EQ(select_glc_candidates(14, 1, 7), (std::vector<std::size_t>{1, 3, 5, 7, 9, 11, 13}));
  EXPECT_EQ(select_glc_candidates(14, 2, 7), select_glc_candidates(14, 0, 7));
  // Over a block's length of iterations every keyframe is visited exactly once.
  std::vector<int> seen(30, 0);
  for (std::size_t it = 0; it < 5; ++it)
    for (auto i : select_glc_candidates(30, it, 7)) ++seen[i];
  for (int s : seen) EXPECT_GE(s, 1);
}

TEST(GlobalLoopClosure, GivenRecencyListThenFrameAndLatestThreeLeftOutBeforeThinning) {
  const LoopOptions o;  // thesis: 7 blocks, the latest 3 excluded
  // Keyframes 10..19 least recently used first; 19 is the frame itself (just made a keyframe).
  std::vector<std::int64_t> recency;
  for (std::int64_t id = 10; id < 20; ++id) recency.push_back(id);
  // Without the frame: 10..18; without the latest 3 (16, 17, 18): 10..15, fewer than 7 blocks.
  EXPECT_EQ(glc_keyframes_to_test(recency, 19, 0, o),
            (std::vector<std::int64_t>{10, 11, 12, 13, 14, 15}));
  // A frame that is not a keyframe: 10..19 minus 17, 18, 19.
  EXPECT_EQ(glc_keyframes_to_test(recency, 99, 0, o),
            (std::vector<std::int64_t>{10, 11, 12, 13, 14, 15, 16}));
  EXPECT_TRUE(glc_keyframes_to_test({1, 2, 3}, 99, 0, o).empty());
}

TEST(GlobalLoopClosure, AcceptanceNeedsMatchShareInlierShareAndMinimumInliers) {
  const LoopOptions o;  // thesis: >= 20 % of features matched, >= 60 % of matches inliers
  EXPECT_TRUE(accept_glc_match(o, 500, 100, 0.60, 60, 10));
  EXPECT_FALSE(accept_glc_match(o, 500, 99, 0.80, 79, 10));   // 19.8 % matched
  EXPECT_FALSE(accept_glc_match(o, 500, 100, 0.59, 59, 10));  // inlier share below 60 %
  EXPECT_FALSE(accept_glc_match(o, 40, 10, 0.90, 9, 10));     // fewer than min_inliers
  EXPECT_FALSE(accept_glc_match(o, 0, 0, 1.0, 0, 0));         // a frame without features
}

}  // namespace
// A registration that "finds" the loop only where the table says so; everything else is a poor
// match. Records what was tested, with which salt.
struct ScriptedRegistration {
  std::map<std::int64_t, std::size_t> inliers_by_kf;  // accepted matches: 100 matched, these kept
  std::vector<std::pair<std::int64_t, std::uint64_t>> tested;
  KeyframeMatch operator()(std::int64_t kf, std::uint64_t salt) {
    tested.emplace_back(kf, salt);
    KeyframeMatch m;
    m.kf = kf;
    m.matches = 100;
    MotionEstimate est;
    const auto it = inliers_by_kf.find(kf);
    const std::size_t kept = it == inliers_by_kf.end() ? 5 : it->second;  // 5 %: refused
    est.inliers.assign(kept, 0);
    est.inlier_ratio = static_cast<double>(kept) / 100.0;
    m.est = est;
    return m;
  }
};

std::vector<std::int64_t> neighbours_by_id(std::int64_t kf) { return {kf - 1, kf + 1}; }

/// A frame with 400 features with depth and the back-end's bar of 10 inliers.
GlcSearchInput search_input(std::int64_t frame_id, const std::vector<std::int64_t>* recency) {
  GlcSearchInput in;
  in.frame_id = frame_id;
  in.n_features = 400;
  in.min_inliers = 10;
  in.recency = recency;
  return in;
}

TEST(GlobalLoopSearch, GivenAnAcceptedCandidateThenABetterCreationNeighbourWins) {
  // GIVEN keyframes 0..9 (least recently used first), the frame 50 with 400 features, and a
  // registration that accepts keyframe 2 (70 inliers) and its later neighbour 3 (80)
  std::vector<std::int64_t> recency{0, 1, 2, 4, 5, 6, 7, 8, 9, 3};
  GlcSearchInput in = search_input(50, &recency);
  ScriptedRegistration reg;
  reg.inliers_by_kf = {{2, 70}, {3, 80}};
  const LoopOptions o;  // thesis: 7 blocks, latest 3 excluded, neighbours tested
  // WHEN the search runs
  const auto found = search_global_loop(in, o, std::ref(reg), neighbours_by_id);
  // THEN the candidates 0..6 (the latest 3 - 8, 9, 3 - left out) were tested first, then the
  // neighbours 1 and 3 of the match with the neighbour salt, and the neighbour with more inliers
  // won
  ASSERT_TRUE(found.has_value());
  EXPECT_EQ(found->kf, 3);
  std::vector<std::pair<std::int64_t, std::uint64_t>> expected{
      {0, 2}, {1, 2}, {2, 2}, {4, 2}, {5, 2}, {6, 2}, {7, 2}, {1, 3}, {3, 3}};
  EXPECT_EQ(reg.tested, expected);
}

TEST(GlobalLoopSearch, GivenNeighboursAlreadyComparedOrTheFrameItselfThenTheyAreNotTestedAgain) {
  // GIVEN the frame became keyframe 3; keyframe 1 is among the latest (not a candidate) and was
  // registered against in the recent-keyframe pass
  std::vector<std::int64_t> recency{0, 2, 4, 5, 6, 7, 8, 9, 1, 3};
  GlcSearchInput in =
      search_input(3, &recency);  // a keyframe made from this frame: never its own loop
  in.already_compared = {1};
  ScriptedRegistration reg;
  reg.inliers_by_kf = {{2, 70}, {1, 90}};
  const auto found = search_global_loop(in, LoopOptions{}, std::ref(reg), neighbours_by_id);
  ASSERT_TRUE(found.has_value());
  EXPECT_EQ(found->kf, 2);  // 1 would be better but was already compared; 3 is the frame
  for (const auto& t : reg.tested) EXPECT_EQ(t.second, 2u);  // no neighbour left to test
}

TEST(GlobalLoopSearch, GivenNothingAcceptedOrNeighboursOffThenNoNeighbourIsTested) {
  std::vector<std::int64_t> recency{0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
  GlcSearchInput in = search_input(50, &recency);
  ScriptedRegistration none;
  EXPECT_FALSE(search_global_loop(in, LoopOptions{}, std::ref(none), neighbours_by_id));
  for (const auto& t : none.tested) EXPECT_EQ(t.second, 2u);
  LoopOptions no_neighbours;
  no_neighbours.glc_test_neighbours = false;
  ScriptedRegistration one;
  one.inliers_by_kf = {{4, 70}, {5, 95}};
  const auto found = search_global_loop(in, no_neighbours, std::ref(one), neighbours_by_id);
  ASSERT_TRUE(found.has_value());
  EXPECT_EQ(found->kf, 5);  // both candidates themselves; the better one
  for (const auto& t : one.tested) EXPECT_EQ(t.second, 2u);
  in.recency = nullptr;
  EXPECT_FALSE(search_global_loop(in, LoopOptions{}, std::ref(one), neighbours_by_id));
}

}  // namespace rgbdquad::slam
