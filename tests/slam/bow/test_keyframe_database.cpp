#include <atomic>
#include <cmath>
#include <set>
#include <thread>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "slam/bow/keyframe_database.h"
#include "slam/bow/vocabulary.h"
#include "common/test_data.h"
#include "slam/features/matching.h"
#include "slam/features/orb_extractor.h"
#include "slam/features/procedural_image.h"
#include "io/tum_dataset.h"

namespace cslam {
namespace {

KeyFrameId kf(ClientId c, std::uint32_t s) { return KeyFrameId{c, s}; }

BowVector normalised(std::map<WordId, double> raw) {
  double sum = 0;
  for (auto& [w, v] : raw) sum += v;
  for (auto& [w, v] : raw) v /= sum;
  return BowVector(raw.begin(), raw.end());
}

TEST(KeyFrameDatabase, HandMadeGroupsAndThresholds) {
  KeyFrameDatabase db;
  const BowVector q = normalised({{1, 1}, {2, 1}, {3, 1}, {4, 1}, {5, 1}});
  db.add(kf(1, 0), normalised({{1, 1}, {2, 1}, {3, 1}, {4, 1}, {9, 1}}));  // 4 common, score 0.8
  db.add(kf(1, 1), normalised({{1, 1}, {2, 1}, {3, 1}, {4, 1}, {8, 3}}));  // 4 common, score ~0.57
  db.add(kf(1, 2), normalised({{1, 1}, {2, 1}, {3, 1}, {5, 1}, {7, 1}}));  // 4 common, score 0.8
  db.add(kf(1, 3), normalised({{1, 1}, {9, 1}}));                          // 1 common: below 80% of 4
  db.add(kf(1, 4), normalised({{20, 1}}));                                 // nothing in common
  EXPECT_EQ(db.size(), 5u);

  // No covisibility: every passing keyframe is its own group; 0.57 < 0.75 * 0.8 is dropped.
  KeyFrameDatabase::QueryParams p;
  auto r = db.query(q, p, nullptr, nullptr);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_NEAR(r[0].score, 0.8, 1e-12);
  EXPECT_EQ(r[0].common_words, 4);
  EXPECT_TRUE((r[0].id == kf(1, 0) && r[1].id == kf(1, 2)) || (r[0].id == kf(1, 2) && r[1].id == kf(1, 0)));

  // Covisibility: kf 1 is a neighbour of kf 2 -> group {2,1} accumulates 0.8 + 0.57 and wins;
  // kf 0 alone (0.8) is below 0.75 * 1.37.
  auto covis = [](KeyFrameId id) {
    if (id == KeyFrameId{1, 2}) return std::vector<KeyFrameId>{{1, 1}, {1, 3}};
    if (id == KeyFrameId{1, 1}) return std::vector<KeyFrameId>{{1, 2}};
    return std::vector<KeyFrameId>{};
  };
  r = db.query(q, p, nullptr, covis);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, kf(1, 2));
  EXPECT_NEAR(r[0].accumulated_score, 0.8 + Vocabulary::score(q, normalised({{1, 1}, {2, 1}, {3, 1}, {4, 1}, {8, 3}})),
              1e-12);

  // min_score removes low candidates; exclude removes keyframes before the common-word test.
  p.min_score = 0.9;
  EXPECT_TRUE(db.query(q, p, nullptr, nullptr).empty());
  p.min_score = 0;
  r = db.query(
      q, p,
      [](KeyFrameId id) {
        return id == KeyFrameId{1, 0} || id == KeyFrameId{1, 2};
      },
      nullptr);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, kf(1, 1));
  p.max_results = 1;
  EXPECT_EQ(db.query(q, p, nullptr, nullptr).size(), 1u);

  // Erase and re-add.
  db.erase(kf(1, 0));
  db.erase(kf(1, 0));  // no-op
  EXPECT_EQ(db.size(), 4u);
  EXPECT_FALSE(db.contains(kf(1, 0)));
  for (const auto& c : db.rank(q)) EXPECT_NE(c.id, kf(1, 0));
  db.add(kf(1, 2), normalised({{30, 1}}));  // replace
  for (const auto& c : db.rank(q)) EXPECT_NE(c.id, kf(1, 2));
  db.clear();
  EXPECT_EQ(db.size(), 0u);
  EXPECT_TRUE(db.query(q, {}, nullptr, nullptr).empty());
}

class WithDefaultVocabulary : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { voc_ = new Vocabulary(Vocabulary::load(default_vocabulary_path())); }
  static void TearDownTestSuite() { delete voc_; }
  static BowVector bow_of(const cv::Mat& img) {
    BowVector b;
    voc_->transform(OrbExtractor().extract(img).descriptors, b);
    return b;
  }
  static Vocabulary* voc_;
};
Vocabulary* WithDefaultVocabulary::voc_ = nullptr;

TEST_F(WithDefaultVocabulary, OwnImageRanksFirst) {
  KeyFrameDatabase db;
  std::vector<BowVector> bows;
  for (std::uint32_t i = 0; i < 12; ++i) {
    bows.push_back(bow_of(procedural_image(90000 + i)));
    db.add(kf(3, i), bows.back());
  }
  for (std::uint32_t i = 0; i < 12; ++i) {
    const auto r = db.query(bows[i], {}, nullptr, nullptr);
    ASSERT_FALSE(r.empty());
    EXPECT_EQ(r[0].id, kf(3, i));
    EXPECT_NEAR(r[0].score, 1.0, 1e-9);
  }
}

TEST_F(WithDefaultVocabulary, OwnRealFrameRanksFirst) {
  CSLAM_REQUIRE_TUM_RPY();
  const TumDataset ds = open_tum_dataset(test::tum_rpy_dir());
  const PinholeCamera cam = camera_tum_fr1();
  const OrbExtractor ex;
  KeyFrameDatabase db;
  std::vector<BowVector> bows;
  for (std::size_t i = 0; i < ds.rgb.size(); i += 40) {
    BowVector b;
    voc_->transform(ex.extract(cv::imread(ds.rgb[i].path, cv::IMREAD_GRAYSCALE), &cam).descriptors, b);
    ASSERT_FALSE(b.empty());
    db.add(kf(1, std::uint32_t(bows.size())), b);
    bows.push_back(b);
  }
  for (std::uint32_t i = 0; i < bows.size(); ++i) {
    const auto r = db.query(bows[i], {}, nullptr, nullptr);
    ASSERT_FALSE(r.empty());
    EXPECT_EQ(r[0].id, kf(1, i));
  }
}

TEST_F(WithDefaultVocabulary, TwoRobotsCrossingTheSamePlace) {
  // A large planar scene; robot A (client 1) drives along y = 900, robot B (client 2) along
  // x = 1200 with its camera rotated by 25 degrees and 15% closer. At the crossing, A's
  // keyframe at x = 1200 must rank first when B's frame queries A's database.
  ProceduralImageConfig sc;
  sc.width = 2400;
  sc.height = 1800;
  sc.shapes = 1500;
  sc.lines = 300;
  sc.texts = 120;
  const cv::Mat scene = procedural_image(424242, sc);
  KeyFrameDatabase db_a;
  std::vector<int> xs;
  for (int x = 300; x <= 2100; x += 300) {
    db_a.add(kf(1, std::uint32_t(xs.size())), bow_of(render_view(scene, x, 900, 0, 1.0)));
    xs.push_back(x);
  }
  const auto r = db_a.query(bow_of(render_view(scene, 1200, 900, 25, 1.15)), {}, nullptr, nullptr);
  ASSERT_FALSE(r.empty());
  EXPECT_EQ(xs[r[0].id.seq], 1200);
  EXPECT_EQ(r[0].id.client, 1);
  // Far from the crossing (no overlap with A's path), no A keyframe scores like the true place.
  const auto far = db_a.rank(bow_of(render_view(scene, 1200, 1700, 25, 1.15)), 1);
  ASSERT_FALSE(far.empty());
  EXPECT_LT(far[0].score, r[0].score);
}

TEST_F(WithDefaultVocabulary, BowMatchingAgreesWithGeometry) {
  const cv::Mat img = procedural_image(777);
  const cv::Mat view = render_view(img, 340, 250, 10, 1.0);  // shifted by (20,10), rotated 10 deg
  const OrbExtractor ex;
  const OrbFeatures a = ex.extract(img), b = ex.extract(view);
  BowVector ba, bb;
  FeatureVector fa, fb;
  voc_->transform(a.descriptors, ba, fa, 4);
  voc_->transform(b.descriptors, bb, fb, 4);
  const auto m = match_by_bow(a, fa, b, fb, MatchParams{});
  ASSERT_GT(m.size(), 100u);
  std::vector<char> used(b.size(), 0);
  for (const Match& x : m) {
    ASSERT_FALSE(used[x.b]);
    used[x.b] = 1;
  }
  // Every match lies under the same direct-index node; mask_b restricts candidates.
  std::vector<char> mask_b(b.size(), 1);
  for (std::size_t i = 0; i < b.size(); i += 2) mask_b[i] = 0;  // 0 = skip
  for (const Match& x : match_by_bow(a, fa, b, fb, MatchParams{}, nullptr, &mask_b)) EXPECT_EQ(x.b % 2, 1);
  // Geometric check: view pixel p maps to scene R(-10deg)(p - c) + (340,250), c = (320,240).
  int good = 0;
  const double t = -10.0 * M_PI / 180.0;
  for (const Match& x : m) {
    const cv::Point2f p = b.keypoints[x.b].pt;
    const double dx = p.x - 320, dy = p.y - 240;
    const double sx = std::cos(t) * dx - std::sin(t) * dy + 340, sy = std::sin(t) * dx + std::cos(t) * dy + 250;
    good += std::hypot(sx - a.keypoints[x.a].pt.x, sy - a.keypoints[x.a].pt.y) < 5.0 * a.keypoints[x.a].size / 31.f;
  }
  EXPECT_GT(good, 0.9 * m.size());
}

TEST(KeyFrameDatabaseThreads, ConcurrentAddEraseQuery) {
  KeyFrameDatabase db;
  std::atomic<bool> stop{false};
  auto bow_for = [](std::uint32_t i) { return normalised({{i % 50, 1}, {50 + i % 7, 1}, {100 + i, 1}}); };
  std::vector<std::thread> writers;
  for (ClientId c = 1; c <= 2; ++c)
    writers.emplace_back([&, c] {
      for (std::uint32_t i = 0; i < 2000; ++i) {
        db.add(kf(c, i), bow_for(i));
        if (i % 3 == 0) db.erase(kf(c, i / 2));
      }
    });
  std::atomic<int> queries{0};
  std::thread reader([&] {
    while (!stop || queries < 200) {
      const auto r = db.query(bow_for(queries % 2000), {}, nullptr, [&](KeyFrameId id) {
        return std::vector<KeyFrameId>{{id.client, id.seq + 1}};
      });
      for (const auto& c : r) ASSERT_GE(c.score, 0.0);
      ++queries;
    }
  });
  for (auto& w : writers) w.join();
  stop = true;
  reader.join();
  EXPECT_GT(queries.load(), 0);
  // Client 1 and 2 each: 2000 added, erased seq i/2 for i = 0,3,6,... (distinct values 0..999 step 1.5).
  std::set<std::uint32_t> erased;
  for (std::uint32_t i = 0; i < 2000; i += 3) erased.insert(i / 2);
  EXPECT_EQ(db.size(), 2 * (2000 - erased.size()));
  // Cross-client query: client 2's keyframe found from a BoW computed elsewhere.
  const auto r = db.rank(bow_for(1999), 2);
  ASSERT_FALSE(r.empty());
  EXPECT_NEAR(r[0].score, 1.0, 1e-12);
  EXPECT_EQ(r[0].id.seq, 1999u);
}

}  // namespace
}  // namespace cslam
