// A frame's bag-of-words vectors are computed only when first needed (with_bow), and then equal
// what the vocabulary gives for its descriptors.
#include <memory>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "slam/bow/vocabulary.h"
#include "slam/features/orb_extractor.h"
#include "slam/features/procedural_image.h"
#include "geometry/camera.h"
#include "slam/map/frame_data.h"

using namespace cslam;

namespace {

struct Fixture {
  PinholeCamera camera = camera_tum_fr1();
  OrbExtractor extractor{OrbConfig{}};
  std::shared_ptr<const ScalePyramid> pyramid = ScalePyramid::from(extractor);
  cv::Mat bgr, depth;
  std::shared_ptr<const Vocabulary> vocabulary;

  Fixture() {
    cv::cvtColor(procedural_image(7), bgr, cv::COLOR_GRAY2BGR);
    depth = cv::Mat(camera.height, camera.width, CV_16UC1, cv::Scalar(2 * camera.depth_factor));
    std::vector<std::vector<Descriptor>> images;
    for (int i = 0; i < 3; ++i) images.push_back(extractor.extract(procedural_image(20 + i)).descriptors);
    VocabularyTrainConfig tc;
    tc.branching = 6;
    tc.depth = 3;
    vocabulary = std::make_shared<const Vocabulary>(Vocabulary::train(images, tc));
  }
  std::shared_ptr<const FrameData> frame(const std::shared_ptr<const Vocabulary>& voc) const {
    return make_frame_data(FrameId{1, 5}, 0.5, bgr, depth, camera, RgbdParams{}, extractor, pyramid, voc, 1);
  }
};

}  // namespace

TEST(FrameBow, LeftPendingUntilAskedForThenEqualToTheVocabularysTransform) {
  const Fixture fx;
  const auto pending = fx.frame(fx.vocabulary);
  ASSERT_GT(pending->size(), 100u);
  EXPECT_TRUE(pending->bow.empty());
  EXPECT_TRUE(pending->feature_vector.empty());
  ASSERT_EQ(pending->pending_bow.vocabulary, fx.vocabulary);

  const auto done = with_bow(pending);
  ASSERT_NE(done, pending);
  EXPECT_FALSE(done->pending_bow.vocabulary);
  BowVector bow;
  FeatureVector fv;
  fx.vocabulary->transform(pending->features.descriptors, bow, fv, 1);
  ASSERT_FALSE(bow.empty());
  EXPECT_EQ(done->bow, bow);
  EXPECT_EQ(done->feature_vector, fv);
  // Everything else is the same frame; the pending original is left as it was.
  EXPECT_EQ(done->id, pending->id);
  EXPECT_EQ(done->size(), pending->size());
  EXPECT_EQ(done->depth, pending->depth);
  EXPECT_EQ(done->features.descriptors, pending->features.descriptors);
  EXPECT_TRUE(pending->bow.empty());
  // Asking again costs nothing: the same object comes back.
  EXPECT_EQ(with_bow(done), done);
}

TEST(FrameBow, NothingPendingWithoutAVocabulary) {
  const Fixture fx;
  const auto f = fx.frame(nullptr);
  EXPECT_FALSE(f->pending_bow.vocabulary);
  EXPECT_EQ(with_bow(f), f);
  EXPECT_TRUE(f->bow.empty());
}
