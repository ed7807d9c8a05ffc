// Loop closing of the local-map SLAM: the bag-of-words vocabulary and inverted index on synthetic
// descriptors (exact results), the shipped vocabulary reproduced by retraining, and the loop closer
// on a synthetic map with injected drift (detection, verification, pose-graph correction, fusion,
// tracking between the solve and the correction).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "slam/dataset/tum_dataset.hpp"
#include "slam/localmap/keyframe_database.hpp"
#include "slam/localmap/loop_closer.hpp"
#include "slam/localmap/map_io.hpp"
#include "slam/localmap/place_index.hpp"
#include "slam/localmap/vocabulary.hpp"

namespace slam {
namespace {

constexpr int kBytes = 32;  // ORB

/// `n` descriptors near `prototype`: each with `flips` distinct random bits flipped.
cv::Mat near(const cv::Mat& prototype, int n, int flips, std::mt19937* rng) {
  cv::Mat out(n, kBytes, CV_8U);
  std::uniform_int_distribution<int> bit(0, kBytes * 8 - 1);
  for (int r = 0; r < n; ++r) {
    prototype.copyTo(out.row(r));
    for (int f = 0; f < flips; ++f) {
      const int b = bit(*rng);
      out.at<std::uint8_t>(r, b / 8) ^= static_cast<std::uint8_t>(1u << (b % 8));
    }
  }
  return out;
}

cv::Mat random_descriptors(int n, std::mt19937* rng) {
  cv::Mat out(n, kBytes, CV_8U);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < kBytes; ++c)
      out.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(byte(*rng));
  return out;
}

cv::Mat stack(const std::vector<cv::Mat>& parts) {
  cv::Mat out;
  cv::vconcat(parts, out);
  return out;
}

TEST(Vocabulary, ThreeSeparatedClustersGiveThreeWordsWithExactIdfAndTfIdf) {
  // GIVEN three prototypes ~128 bits apart and descriptors within 4 bits of them
  std::mt19937 rng(7);
  const cv::Mat p = random_descriptors(3, &rng);
  const cv::Mat g0 = near(p.row(0), 20, 4, &rng), g1 = near(p.row(1), 20, 4, &rng),
                g2 = near(p.row(2), 20, 4, &rng);
  // three training images: {g0, g1}, {g1, g2}, {g0}
  const std::vector<cv::Mat> images{stack({g0, g1}), stack({g1, g2}), g0.clone()};
  VocabularyOptions o;
  o.branching = 3;
  o.levels = 1;
  std::string err;
  // WHEN a one-level, three-branch vocabulary is trained
  const auto v = BinaryVocabulary::train(images, o, &err);
  ASSERT_TRUE(v) << err;
  // THEN each group is one word, and the words differ
  ASSERT_EQ(v->words(), 3u);
  const std::uint32_t w0 = v->word_of(g0.ptr<std::uint8_t>(0)),
                      w1 = v->word_of(g1.ptr<std::uint8_t>(0)),
                      w2 = v->word_of(g2.ptr<std::uint8_t>(0));
  EXPECT_NE(w0, w1);
  EXPECT_NE(w1, w2);
  EXPECT_NE(w0, w2);
  for (int r = 0; r < 20; ++r) {
    EXPECT_EQ(v->word_of(g0.ptr<std::uint8_t>(r)), w0);
    EXPECT_EQ(v->word_of(g1.ptr<std::uint8_t>(r)), w1);
    EXPECT_EQ(v->word_of(g2.ptr<std::uint8_t>(r)), w2);
  }
  // idf = log(N / n_i): g0 and g1 in 2 of 3 images, g2 in 1
  EXPECT_DOUBLE_EQ(v->idf(w0), std::log(3.0 / 2.0));
  EXPECT_DOUBLE_EQ(v->idf(w1), std::log(3.0 / 2.0));
  EXPECT_DOUBLE_EQ(v->idf(w2), std::log(3.0));
  // tf-idf of 10 x g0 + 30 x g2, L1-normalised: (10 log 1.5, 30 log 3) / sum
  const BowVector bow = v->transform(stack({g0.rowRange(0, 10), near(p.row(2), 30, 4, &rng)}));
  ASSERT_EQ(bow.size(), 2u);
  const double a = 10 * std::log(1.5), b = 30 * std::log(3.0);
  for (const auto& [w, x] : bow) EXPECT_NEAR(x, (w == w0 ? a : b) / (a + b), 1e-15);
  EXPECT_DOUBLE_EQ(bow_score(bow, bow), 1.0);
  EXPECT_DOUBLE_EQ(bow_score(bow, v->transform(g1)), 0.0);
  // the byte form reads back to the same vocabulary; one flipped byte is refused
  std::vector<std::uint8_t> bytes = v->to_bytes();
  const auto back = BinaryVocabulary::from_bytes(bytes, &err);
  ASSERT_TRUE(back) << err;
  EXPECT_EQ(back->to_bytes(), bytes);
  bytes[bytes.size() / 2] ^= 0x10;
  EXPECT_FALSE(BinaryVocabulary::from_bytes(bytes, &err));
  EXPECT_NE(err.find("checksum"), std::string::npos) << err;
}

TEST(KeyframeDatabase, InvertedIndexScoresOnlySharedWordsAndHonoursExclusions) {
  KeyframeDatabase db;
  db.add(1, {{0, 0.5}, {1, 0.5}});
  db.add(2, {{1, 0.25}, {2, 0.75}});
  db.add(3, {{3, 1.0}});
  const BowVector q{{0, 0.25}, {1, 0.25}, {2, 0.5}};
  // scores: kf1 min(.25,.5)+min(.25,.5) = 0.5; kf2 min(.25,.25)+min(.5,.75) = 0.75; kf3 shares
  // nothing
  auto hits = db.query(q, {}, 0.0, 10);
  ASSERT_EQ(hits.size(), 2u);
  EXPECT_EQ(hits[0].keyframe, 2);
  EXPECT_DOUBLE_EQ(hits[0].score, 0.75);
  EXPECT_EQ(hits[0].common_words, 2);
  EXPECT_EQ(hits[1].keyframe, 1);
  EXPECT_DOUBLE_EQ(hits[1].score, 0.5);
  EXPECT_DOUBLE_EQ(hits[0].score, bow_score(q, *db.vector(2)));
  // a bar, an exclusion, a cap, an erase
  EXPECT_EQ(db.query(q, {}, 0.6, 10).size(), 1u);
  EXPECT_EQ(db.query(q, {2}, 0.0, 10).front().keyframe, 1);
  EXPECT_EQ(db.query(q, {}, 0.0, 1).size(), 1u);
  db.erase(2);
  hits = db.query(q, {}, 0.0, 10);
  ASSERT_EQ(hits.size(), 1u);
  EXPECT_EQ(hits[0].keyframe, 1);
  EXPECT_EQ(db.size(), 2u);
}

TEST(Vocabulary, TheCompiledInVocabularyIsWhatTrainingOnTheShippedFramesGives) {
  // The shipped file is `slam-eval vocab --dataset tests/data/fr1_desk_9frames` (ORB defaults).
  std::string err;
  const auto builtin = builtin_orb_vocabulary(&err);
  ASSERT_TRUE(builtin) << err;
  EXPECT_EQ(builtin->words(), 1000u);
  auto ds = TumDataset::open(std::string(SLAM_REPO_DIR) + "/tests/data/fr1_desk_9frames",
                             TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  FeatureOptions fo;
  fo.kind = DetectorKind::kOrb;
  auto ex = FeatureExtractor::create(fo, Intrinsics{}, &err);
  ASSERT_TRUE(ex) << err;
  std::vector<cv::Mat> images;
  for (std::size_t i = 0; i < ds->size(); ++i) {
    auto f = ds->load(i, &err);
    ASSERT_TRUE(f) << err;
    auto feats = ex->extract(*f, &err);
    ASSERT_TRUE(feats) << err;
    images.push_back(feats->descriptors.clone());
  }
  const auto v = BinaryVocabulary::train(images, VocabularyOptions{}, &err);
  ASSERT_TRUE(v) << err;
  EXPECT_EQ(v->to_bytes(), builtin_orb_vocabulary_bytes())
      << "retrain with: slam-eval vocab --dataset tests/data/fr1_desk_9frames --out "
         "offboard/slam/data/orb_vocabulary_k10_l3.bin";
}

// --- a synthetic map with drift and a revisit
// -----------------------------------------------------

Eigen::Isometry3d pose_at(double x, double y, double yaw_rad) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitY()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, 0);
  return T;
}

/// A distinct noise image per keyframe, so that the thumbnail ranking finds the right one.
cv::Mat image_of(std::int64_t id) {
  cv::Mat img(480, 640, CV_8UC3);
  cv::RNG rng(static_cast<std::uint64_t>(id) + 1);
  rng.fill(img, cv::RNG::UNIFORM, 0, 256);
  return img;
}

struct Landmark {
  Eigen::Vector3d p_world_m;
  cv::Mat descriptor;
};

/// A keyframe seeing `seen` landmarks from true pose `T_true`; its pose in the map is `T_map` and
/// its new points are placed through it (as the tracker does), `known` maps landmark -> point id.
struct SyntheticWorld {
  CameraModel cam = CameraModel::from(Intrinsics{});
  std::vector<Landmark> landmarks;
  std::vector<Eigen::Isometry3d> truth;
  std::shared_ptr<SharedMap> map = std::make_shared<SharedMap>();

  /// Landmarks 1-3 m in front of the true camera pose T.
  std::vector<int> make_landmarks(const Eigen::Isometry3d& T, int n, std::mt19937* rng) {
    std::uniform_real_distribution<double> u(-1.0, 1.0), z(1.0, 3.0);
    std::vector<int> ids;
    for (int i = 0; i < n; ++i) {
      const double d = z(*rng);
      const Eigen::Vector3d pc(0.5 * u(*rng) * d, 0.4 * u(*rng) * d, d);
      landmarks.push_back(Landmark{T * pc, random_descriptors(1, rng)});
      ids.push_back(static_cast<int>(landmarks.size()) - 1);
    }
    return ids;
  }

  /// Features of landmarks `seen` from T_true (or, for those in `view_from`, from another pose: a
  /// synthetic shortcut that links the revisit to the walk's last keyframe without moving them).
  std::shared_ptr<FrameFeatures> features_of(
      const Eigen::Isometry3d& T_true, const std::vector<int>& seen,
      const std::map<int, Eigen::Isometry3d>& view_from = {}) const {
    auto f = std::make_shared<FrameFeatures>();
    f->descriptors.create(static_cast<int>(seen.size()), kBytes, CV_8U);
    for (std::size_t k = 0; k < seen.size(); ++k) {
      const auto v = view_from.find(seen[k]);
      const Eigen::Isometry3d& T_view = v == view_from.end() ? T_true : v->second;
      const Eigen::Vector3d pc =
          T_view.inverse() * landmarks[static_cast<std::size_t>(seen[k])].p_world_m;
      const Eigen::Vector3d uvd = cam.project(pc);
      f->keypoints.emplace_back(
          cv::Point2f(static_cast<float>(uvd.x()), static_cast<float>(uvd.y())), 31.0f);
      f->points_cam_m.push_back(pc);
      f->colours_bgr.emplace_back(0, 0, 0);
      landmarks[static_cast<std::size_t>(seen[k])].descriptor.copyTo(
          f->descriptors.row(static_cast<int>(k)));
    }
    f->detected = seen.size();
    return f;
  }

  void add_keyframe(std::int64_t id, const Eigen::Isometry3d& T_true,
                    const Eigen::Isometry3d& T_map, const std::vector<int>& seen,
                    std::map<int, std::int64_t>* known,
                    const std::map<int, Eigen::Isometry3d>& view_from = {}) {
    FeatureOptions fo;
    fo.kind = DetectorKind::kOrb;
    MapKeyframe kf;
    kf.id = id;
    kf.T_world_cam = T_map;
    kf.thumbnail = make_thumbnail(image_of(id));
    kf.features = TrackedFeatures::from(features_of(T_true, seen, view_from), cam, fo);
    SlamMap& m = map->map;
    m.add_keyframe(kf);
    const MapKeyframe* k = m.keyframe(id);
    for (std::size_t i = 0; i < seen.size(); ++i) {
      auto it = known->find(seen[i]);
      if (it != known->end()) {
        m.add_observation(it->second, id, static_cast<int>(i));
      } else {
        const std::int64_t pid = m.add_point(
            T_map * k->features.features->points_cam_m[i],
            k->features.features->descriptors.row(static_cast<int>(i)), id, static_cast<int>(i));
        (*known)[seen[i]] = pid;
      }
    }
    truth.push_back(T_true);
  }
};

constexpr int kWalk = 11;
constexpr double kDriftPerKeyframeM = 0.02;

/// Keyframes 0..10 walk along x (2 cm of drift per keyframe injected into the map poses), each
/// sharing 60 landmarks with the previous one; keyframe 11 comes back to keyframe 0's place (140 of
/// its landmarks, as new points: the map has not connected them) with 22 cm of drift, and shares
/// 60 points with keyframe 10 (its covisible neighbour, which sets the detection bar).
SyntheticWorld drifting_walk_with_revisit(std::vector<int>* last_walk_landmarks = nullptr) {
  SyntheticWorld w;
  std::mt19937 rng(11);
  constexpr double kStepM = 0.25;
  std::map<int, std::int64_t> known;
  std::vector<int> previous;
  std::vector<int> first_place;
  for (int i = 0; i < kWalk; ++i) {
    const Eigen::Isometry3d T_true = pose_at(kStepM * i, 0, 0.05 * i);
    const Eigen::Isometry3d T_map = pose_at(kStepM * i + kDriftPerKeyframeM * i, 0, 0.05 * i);
    std::vector<int> seen(previous.begin(),
                          previous.begin() + std::min<std::size_t>(60, previous.size()));
    const std::vector<int> fresh =
        w.make_landmarks(T_true, 200 - static_cast<int>(seen.size()), &rng);
    seen.insert(seen.end(), fresh.begin(), fresh.end());
    if (i == 0) first_place = seen;
    w.add_keyframe(i, T_true, T_map, seen, &known);
    previous = fresh;
  }
  // The revisit: keyframe 0's place from 2 cm beside it, plus 60 landmarks shared with keyframe 10.
  const Eigen::Isometry3d T_true = pose_at(0.02, 0, 0);
  const Eigen::Isometry3d T_map = pose_at(0.02 + kDriftPerKeyframeM * kWalk, 0, 0);
  std::map<int, std::int64_t> fresh_points;  // place A seen again: new points, not yet connected
  for (int id : previous) fresh_points[id] = known[id];
  std::vector<int> seen(first_place.begin(), first_place.begin() + 140);
  std::vector<int> near_previous(previous.begin(), previous.begin() + 60);
  std::map<int, Eigen::Isometry3d> view_from;
  for (int id : near_previous) view_from[id] = w.truth[10];
  seen.insert(seen.end(), near_previous.begin(), near_previous.end());
  w.add_keyframe(kWalk, T_true, T_map, seen, &fresh_points, view_from);
  if (last_walk_landmarks) *last_walk_landmarks = previous;
  return w;
}

double position_rmse_m(const SyntheticWorld& w) {
  double s = 0;
  for (std::size_t i = 0; i < w.truth.size(); ++i)  // truth[11] is the revisit
    s += (w.map->map.keyframe(static_cast<std::int64_t>(i))->T_world_cam.translation() -
          w.truth[i].translation())
             .squaredNorm();
  return std::sqrt(s / static_cast<double>(w.truth.size()));
}

std::optional<LoopCloser> make_closer(const SyntheticWorld& w) {
  std::string err;
  auto vocabulary = builtin_orb_vocabulary(&err);
  EXPECT_TRUE(vocabulary) << err;
  if (!vocabulary) return std::nullopt;
  LoopCloserOptions o;
  o.matching.lowe_ratio = 0.75;
  auto c = LoopCloser::create(
      o, w.cam, w.map, std::make_shared<const BinaryVocabulary>(std::move(*vocabulary)), &err);
  EXPECT_TRUE(c) << err;
  return c;
}

TEST(LoopCloser, DetectsTheRevisitAndThePoseGraphRemovesTheInjectedDrift) {
  // GIVEN a walk with 1 cm of drift per keyframe that returns to its start
  SyntheticWorld w = drifting_walk_with_revisit();
  auto closer = make_closer(w);
  ASSERT_TRUE(closer);
  const double before_m = position_rmse_m(w);
  const std::size_t points_before = w.map->map.points().size();
  // WHEN every keyframe goes through the loop closer in order
  std::vector<LoopStats> stats;
  for (std::int64_t id = 0; id <= 11; ++id) stats.push_back(closer->process(id));
  // THEN no loop is claimed along the walk, and the revisit closes the loop with keyframe 0
  for (std::size_t i = 0; i + 1 < stats.size(); ++i) EXPECT_FALSE(stats[i].accepted) << i;
  const LoopStats& last = stats.back();
  ASSERT_TRUE(last.accepted) << "candidates " << last.candidates << ", ransac-verified "
                             << last.verified_ransac;
  EXPECT_EQ(last.loop_keyframe, 0);
  EXPECT_GE(last.fit_inliers, 100);
  EXPECT_NEAR(last.correction_m, kDriftPerKeyframeM * kWalk, 0.01);
  ASSERT_EQ(w.map->map.loop_edges().size(), 1u);
  EXPECT_EQ(w.map->corrections, 1u);
  // the drift (a linear ramp) is spread back over the walk: keyframe positions near the truth
  const double after_m = position_rmse_m(w);
  EXPECT_LT(after_m, 0.2 * before_m) << "before " << before_m << " m, after " << after_m << " m";
  // the revisit's duplicate points were merged into the old ones
  EXPECT_GE(last.points_merged, 100);
  EXPECT_LT(w.map->map.points().size(), points_before);
  // and the loop edge survives a save / load (map format version 2)
  const std::string path = ::testing::TempDir() + "/loop_edge.map";
  std::string err;
  FeatureOptions fo;
  fo.kind = DetectorKind::kOrb;
  ASSERT_TRUE(save_map(path, w.map->map, MapFileContext{w.cam, fo}, &err)) << err;
  const auto loaded = load_map(path, MapFileContext{w.cam, fo}, &err);
  ASSERT_TRUE(loaded) << err;
  ASSERT_EQ(loaded->loop_edges().size(), 1u);
  EXPECT_TRUE(loaded->loop_edges()[0].T_a_b.isApprox(w.map->map.loop_edges()[0].T_a_b, 1e-12));
}

TEST(LoopCloser, TrackingProceedsBetweenTheSolveAndTheCorrectionAndFollowsIt) {
  // GIVEN the drifting walk, the revisit keyframe detected and its pose graph solved
  std::vector<int> walk_end;
  SyntheticWorld w = drifting_walk_with_revisit(&walk_end);
  auto closer = make_closer(w);
  ASSERT_TRUE(closer);
  LoopStats st;
  for (std::int64_t id = 0; id <= 10; ++id) closer->process(id);
  const auto loop = closer->detect(11, &st);
  ASSERT_TRUE(loop);
  const auto correction = closer->optimise(*loop, &st);
  ASSERT_TRUE(correction);
  // WHEN a tracker tracks keyframe 10's view (the drifted end of the walk) before and after the
  // correction is applied
  std::string err;
  TrackerOptions to;
  to.matching.lowe_ratio = 0.75;
  auto tracker = Tracker::create(to, w.cam, w.map, &err);
  ASSERT_TRUE(tracker) << err;
  FeatureOptions fo;
  fo.kind = DetectorKind::kOrb;
  const auto view = std::shared_ptr<const FrameFeatures>(w.features_of(w.truth[10], walk_end));
  RgbdFrame f;
  f.rgb = image_of(10);  // looks like keyframe 10
  f.index = 100;
  f.stamp_s = 10.0;
  tracker->set_lost();
  const TrackResult a = tracker->track(f, view, fo, false);
  ASSERT_EQ(a.state, TrackingState::kTracking)
      << "the map lock must be free while the graph is solved";
  const Eigen::Isometry3d kf10_before = w.map->map.keyframe(10)->T_world_cam;
  EXPECT_LT((a.T_world_cam.translation() - kf10_before.translation()).norm(), 0.01);
  closer->apply(*correction, &st);
  const Eigen::Isometry3d kf10_after = w.map->map.keyframe(10)->T_world_cam;
  ASSERT_GT((kf10_after.translation() - kf10_before.translation()).norm(), 0.15);
  f.index = 101;
  f.stamp_s = 10.033;
  const TrackResult b = tracker->track(f, view, fo, false);
  // THEN tracking continues without a loss or a relocalisation, in the corrected frame: the last
  // pose moved with its reference keyframe (otherwise the 0.2 m step would be refused as a jump)
  ASSERT_EQ(b.state, TrackingState::kTracking);
  EXPECT_FALSE(b.relocalised);
  EXPECT_LT((b.T_world_cam.translation() - kf10_after.translation()).norm(), 0.01);
  EXPECT_LT((b.T_world_cam.translation() - w.truth[10].translation()).norm(), 0.03);
  EXPECT_GT(st.apply_lock_ms, 0.0);
}

}  // namespace
}  // namespace slam

namespace slam {
namespace {

TEST(Relocalisation, RefitsAroundTheKeyframeRansacFoundNotTheFirstCandidate) {
  // GIVEN two places 5 m apart that share no point: keyframe 0 at A, keyframe 1 at B
  SyntheticWorld w;
  std::mt19937 rng(31);
  const Eigen::Isometry3d T_a = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_b = Eigen::Isometry3d::Identity();
  T_b.translation() = Eigen::Vector3d(5.0, 0.0, 0.0);
  const std::vector<int> at_a = w.make_landmarks(T_a, 200, &rng);
  const std::vector<int> at_b = w.make_landmarks(T_b, 200, &rng);
  std::map<int, std::int64_t> known;
  w.add_keyframe(0, T_a, T_a, at_a, &known);
  w.add_keyframe(1, T_b, T_b, at_b, &known);
  std::string err;
  TrackerOptions to;
  to.matching.lowe_ratio = 0.75;
  auto tracker = Tracker::create(to, w.cam, w.map, &err);
  ASSERT_TRUE(tracker) << err;
  FeatureOptions fo;
  fo.kind = DetectorKind::kOrb;
  // and a tracker tracking at A (its reference keyframe is 0)
  RgbdFrame f;
  f.rgb = image_of(0);
  f.index = 100;
  f.stamp_s = 1.0;
  tracker->set_lost();
  const TrackResult a = tracker->track(f, w.features_of(T_a, at_a), fo, false);
  ASSERT_EQ(a.state, TrackingState::kTracking);
  ASSERT_EQ(a.reference_keyframe, 0);
  // WHEN the next frame (10 s later: a stalled link) sees place B, looking like A by thumbnail, so
  // the reference keyframe 0 heads the candidate list and only keyframe 1 registers by RANSAC
  f.index = 101;
  f.stamp_s = 11.0;
  const TrackResult b = tracker->track(f, w.features_of(T_b, at_b), fo, false);
  // THEN the refit runs against keyframe 1's local map and tracking resumes at B
  ASSERT_EQ(b.state, TrackingState::kTracking);
  EXPECT_TRUE(b.relocalised);
  EXPECT_EQ(b.reference_keyframe, 1);
  EXPECT_LT((b.T_world_cam.translation() - T_b.translation()).norm(), 0.01);
}

}  // namespace
}  // namespace slam

namespace slam {
namespace {

/// One keyframe seeing 200 near landmarks; a tracker tracking it; then a frame 1 cm away that sees
/// `still_seen` of them plus 150 landmarks beyond the near depth (so the near rule stays quiet).
TrackResult track_view_change(int still_seen, bool mapper_idle) {
  SyntheticWorld w;
  std::mt19937 rng(41);
  const Eigen::Isometry3d T0 = Eigen::Isometry3d::Identity();
  const std::vector<int> near = w.make_landmarks(T0, 200, &rng);
  Eigen::Isometry3d T_far = Eigen::Isometry3d::Identity();
  T_far.translation() =
      Eigen::Vector3d(0, 0, 2.5);  // landmarks 3.5-5.5 m deep: beyond ThDepth 3.1 m
  const std::vector<int> far = w.make_landmarks(T_far, 150, &rng);
  std::map<int, std::int64_t> known;
  w.add_keyframe(0, T0, T0, near, &known);
  std::string err;
  TrackerOptions to;
  to.matching.lowe_ratio = 0.75;
  auto tracker = Tracker::create(to, w.cam, w.map, &err);
  EXPECT_TRUE(tracker) << err;
  FeatureOptions fo;
  fo.kind = DetectorKind::kOrb;
  RgbdFrame f;
  f.rgb = image_of(0);
  f.index = 100;
  f.stamp_s = 1.0;
  tracker->set_lost();
  const TrackResult first = tracker->track(f, w.features_of(T0, near), fo, true, true);
  EXPECT_EQ(first.state, TrackingState::kTracking);
  EXPECT_FALSE(first.keyframe);
  Eigen::Isometry3d T1 = Eigen::Isometry3d::Identity();
  T1.translation() = Eigen::Vector3d(0.01, 0, 0);
  std::vector<int> seen(near.begin(), near.begin() + still_seen);
  seen.insert(seen.end(), far.begin(), far.end());
  f.index = 101;
  f.stamp_s = 1.033;
  return tracker->track(f, w.features_of(T1, seen), fo, true, mapper_idle);
}

TEST(KeyframeGate, WhileTheMapperIsBusyOnlyWeakTrackingMakesAKeyframe) {
  // GIVEN a view change (70 of the reference's 200 points tracked: < 0.4 x 200 while the map has
  // one keyframe) that is not weak tracking (>= 0.25 x 200) WHEN the mapper is idle THEN a keyframe
  // is made
  const TrackResult idle = track_view_change(70, true);
  ASSERT_EQ(idle.state, TrackingState::kTracking);
  EXPECT_TRUE(idle.keyframe);
  EXPECT_EQ(idle.keyframe_wanted, KeyframeReason::kViewChanged);
  // WHEN the mapper is busy THEN it is left for later (ORB-SLAM2 c1b/c1c)
  const TrackResult busy = track_view_change(70, false);
  ASSERT_EQ(busy.state, TrackingState::kTracking);
  EXPECT_FALSE(busy.keyframe);
  EXPECT_EQ(busy.keyframe_wanted, KeyframeReason::kMapperBusy);
  // WHEN tracking is weak (40 < 0.25 x 200) THEN a keyframe is made even with the mapper busy
  const TrackResult weak = track_view_change(40, false);
  ASSERT_EQ(weak.state, TrackingState::kTracking);
  EXPECT_TRUE(weak.keyframe);
}

}  // namespace
}  // namespace slam
