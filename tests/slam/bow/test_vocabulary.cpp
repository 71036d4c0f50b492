#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

#include <gtest/gtest.h>

#include "slam/bow/kmajority.h"
#include "slam/bow/vocabulary.h"
#include "core/error.h"
#include "slam/features/orb_extractor.h"
#include "slam/features/procedural_image.h"

namespace cslam {
namespace {

Descriptor from_bits(const std::vector<int>& bits) {
  Descriptor d{0, 0, 0, 0};
  for (int b : bits) reinterpret_cast<std::uint8_t*>(d.data())[b >> 3] |= std::uint8_t(1u << (b & 7));
  return d;
}

TEST(KMajority, MajorityOnHandMadeExample) {
  // bit 0 set in 3/4, bit 1 in 2/4 (tie -> 0), bit 100 in 4/4, bit 255 in 1/4, bit 8 in 3/4.
  const std::vector<Descriptor> all{from_bits({0, 1, 100, 8}), from_bits({0, 100, 8}), from_bits({0, 1, 100, 255}),
                                    from_bits({100, 8})};
  EXPECT_EQ(majority_descriptor(all, {0, 1, 2, 3}), from_bits({0, 8, 100}));
  // Subset of three: bit 1 in 2/3 -> set; bit 8 in 2/3 -> set; bit 255 in 1/3 -> not set.
  EXPECT_EQ(majority_descriptor(all, {0, 1, 2}), from_bits({0, 1, 8, 100}));
  EXPECT_EQ(majority_descriptor(all, {3}), all[3]);
  EXPECT_EQ(majority_descriptor(all, {}), from_bits({}));
}

TEST(KMajority, MajorityCountsBeyondLaneOverflow) {
  // 600 members (> 255 per SWAR lane): 301 have bit 5, 299 have bit 6.
  std::vector<Descriptor> all;
  std::vector<std::uint32_t> members;
  for (int i = 0; i < 600; ++i) {
    all.push_back(from_bits(i < 301 ? std::vector<int>{5} : std::vector<int>{6}));
    members.push_back(std::uint32_t(i));
  }
  EXPECT_EQ(majority_descriptor(all, members), from_bits({5}));
}

TEST(KMajority, SeparatesTwoClusters) {
  std::mt19937_64 rng(5);
  const Descriptor c0{rng(), rng(), rng(), rng()}, c1{rng(), rng(), rng(), rng()};
  std::vector<Descriptor> all;
  std::vector<std::uint32_t> members;
  for (int i = 0; i < 200; ++i) {
    Descriptor d = i % 2 ? c1 : c0;
    for (int k = 0; k < 10; ++k) d[rng() % 4] ^= 1ull << (rng() % 64);  // a few flipped bits
    all.push_back(d);
    members.push_back(std::uint32_t(i));
  }
  const KMajorityResult r = kmajority(all, members, 2, 10, 1);
  ASSERT_EQ(r.centers.size(), 2u);
  for (const auto& cl : r.clusters) {
    ASSERT_EQ(cl.size(), 100u);
    for (std::uint32_t m : cl) EXPECT_EQ(m % 2, cl.front() % 2);
  }
  // Majority recovers the original centres exactly (bits are flipped rarely and independently).
  for (const Descriptor& c : r.centers) EXPECT_TRUE(c == c0 || c == c1);
}

// words_of against word_of one descriptor at a time: random descriptors and `known` ones, batch
// sizes around the lock-step batch (16), every direct-index level.
void expect_batch_matches_one_by_one(const Vocabulary& voc, const std::vector<Descriptor>& known) {
  std::mt19937_64 rng(5);
  std::vector<Descriptor> all = known;
  for (int i = 0; i < 300; ++i) all.push_back({rng(), rng(), rng(), rng()});
  for (const std::size_t n : {std::size_t(0), std::size_t(1), std::size_t(15), std::size_t(16), std::size_t(17),
                              std::size_t(33), all.size()}) {
    for (int levels_up = 0; levels_up <= voc.depth() + 1; ++levels_up) {
      std::vector<WordId> words(n, WordId(-1));
      std::vector<NodeId> nodes(n, NodeId(-1));
      voc.words_of(all.data(), n, levels_up, words.data(), nodes.data());
      for (std::size_t i = 0; i < n; ++i) {
        NodeId node = 0;
        ASSERT_EQ(words[i], voc.word_of(all[i], levels_up, node)) << "descriptor " << i << " of " << n;
        ASSERT_EQ(nodes[i], node) << "descriptor " << i << " of " << n << ", levels_up " << levels_up;
      }
    }
  }
}

// A small vocabulary trained on procedural images (k=10, L=4: leaves are single descriptors).
class SmallVocabulary : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    OrbConfig oc;
    oc.num_features = 150;
    const OrbExtractor ex(oc);
    images_ = new std::vector<std::vector<Descriptor>>();
    for (int i = 0; i < 4; ++i) images_->push_back(ex.extract(procedural_image(500 + i)).descriptors);
    VocabularyTrainConfig tc;
    tc.branching = 10;
    tc.depth = 4;
    voc_ = new Vocabulary(Vocabulary::train(*images_, tc));
  }
  static void TearDownTestSuite() {
    delete voc_;
    delete images_;
  }
  static std::vector<std::vector<Descriptor>>* images_;
  static Vocabulary* voc_;
};
std::vector<std::vector<Descriptor>>* SmallVocabulary::images_ = nullptr;
Vocabulary* SmallVocabulary::voc_ = nullptr;

TEST_F(SmallVocabulary, TrainingDescriptorLandsInItsOwnLeaf) {
  ASSERT_FALSE(voc_->empty());
  EXPECT_EQ(voc_->branching(), 10);
  EXPECT_EQ(voc_->depth(), 4);
  for (const auto& img : *images_)
    for (const Descriptor& d : img) ASSERT_EQ(voc_->word_descriptor(voc_->word_of(d)), d);
}

TEST_F(SmallVocabulary, SaveLoadRoundTripIsBitExact) {
  const std::string path = ::testing::TempDir() + "/cslam_test_vocab.voc", path2 = path + "2";
  voc_->save(path);
  const Vocabulary loaded = Vocabulary::load(path);
  EXPECT_TRUE(loaded == *voc_);
  loaded.save(path2);
  std::ifstream a(path, std::ios::binary), b(path2, std::ios::binary);
  const std::string sa((std::istreambuf_iterator<char>(a)), {}), sb((std::istreambuf_iterator<char>(b)), {});
  EXPECT_EQ(sa, sb);
  for (const auto& img : *images_) {
    BowVector v1, v2;
    voc_->transform(img, v1);
    loaded.transform(img, v2);
    EXPECT_EQ(v1, v2);
  }
  std::remove(path.c_str());
  std::remove(path2.c_str());
}

void expect_input_error(const std::string& path, const std::string& fragment) {
  try {
    Vocabulary::load(path);
    ADD_FAILURE() << "no error for " << fragment;
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path), std::string::npos) << what;
    EXPECT_NE(what.find(fragment), std::string::npos) << what;
  }
}

TEST_F(SmallVocabulary, CorruptFilesGiveClearErrors) {
  const std::string path = ::testing::TempDir() + "/cslam_test_vocab_bad.voc";
  voc_->save(path);
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign((std::istreambuf_iterator<char>(in)), {});
  }
  auto write = [&](const std::string& b) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(b.data(), std::streamsize(b.size()));
  };
  std::string flipped = bytes;
  flipped[flipped.size() / 2] ^= 0x10;
  write(flipped);
  expect_input_error(path, "checksum");
  write(bytes.substr(0, bytes.size() - 7));
  expect_input_error(path, "truncated");
  write(bytes.substr(0, 20));
  expect_input_error(path, "truncated");
  std::string version = bytes;
  version[8] = 9;
  write(version);
  expect_input_error(path, "version");
  std::string magic = bytes;
  magic[0] = 'X';
  write(magic);
  expect_input_error(path, "magic");
  write(bytes + "junk");
  expect_input_error(path, "trailing");
  write("");
  expect_input_error(path, "truncated");
  std::remove(path.c_str());
  expect_input_error(path, "cannot open");
}

TEST_F(SmallVocabulary, TransformIsNormalisedWithDirectIndex) {
  BowVector bow;
  FeatureVector fv;
  const auto& img = (*images_)[0];
  voc_->transform(img, bow, fv, 2);
  ASSERT_FALSE(bow.empty());
  double sum = 0;
  for (const auto& [w, v] : bow) {
    EXPECT_GT(v, 0);
    sum += v;
  }
  EXPECT_NEAR(sum, 1.0, 1e-9);
  std::size_t indexed = 0;
  for (const auto& [node, idx] : fv) {
    indexed += idx.size();
    EXPECT_TRUE(std::is_sorted(idx.begin(), idx.end()));
    for (int i : idx) {
      NodeId n;
      voc_->word_of(img[i], 2, n);
      EXPECT_EQ(n, node);
    }
  }
  std::size_t weighted = 0;
  for (const Descriptor& d : img) weighted += voc_->word_weight(voc_->word_of(d)) > 0;
  EXPECT_EQ(indexed, weighted);
  EXPECT_LE(fv.size(), 100u);  // at most k^(L-2) nodes at depth 2
  // levels_up >= depth: everything under the root.
  voc_->transform(img, bow, fv, 10);
  ASSERT_EQ(fv.size(), 1u);
  EXPECT_EQ(fv.begin()->first, 0u);
  // Empty input.
  voc_->transform({}, bow, fv, 2);
  EXPECT_TRUE(bow.empty());
  EXPECT_TRUE(fv.empty());
}

TEST(VocabularyScore, L1ScoreOfDBoW2) {
  const BowVector a{{1, 0.5}, {2, 0.5}}, b{{2, 0.5}, {3, 0.5}}, c{{4, 1.0}};
  EXPECT_DOUBLE_EQ(Vocabulary::score(a, a), 1.0);
  EXPECT_DOUBLE_EQ(Vocabulary::score(a, c), 0.0);
  EXPECT_DOUBLE_EQ(Vocabulary::score(a, b), 0.5);  // 1 - 0.5 * (0.5 + 0 + 0.5)
  const BowVector d{{1, 0.2}, {2, 0.8}};
  EXPECT_NEAR(Vocabulary::score(a, d), 1 - 0.5 * (0.3 + 0.3), 1e-12);
  EXPECT_DOUBLE_EQ(Vocabulary::score(a, d), Vocabulary::score(d, a));
  EXPECT_DOUBLE_EQ(Vocabulary::score({}, a), 0.0);
}

TEST(VocabularyTrain, RejectsBadConfig) {
  VocabularyTrainConfig c;
  c.branching = 1;
  EXPECT_THROW(Vocabulary::train({{Descriptor{1, 2, 3, 4}}}, c), ConfigError);
  EXPECT_THROW(Vocabulary::train({}, VocabularyTrainConfig{}), ConfigError);
  // An empty vocabulary transforms to empty vectors; asking for a word is a programming error.
  const Vocabulary empty;
  BowVector bow;
  empty.transform({Descriptor{1, 2, 3, 4}}, bow);
  EXPECT_TRUE(bow.empty());
  EXPECT_THROW(empty.word_of(Descriptor{1, 2, 3, 4}), std::logic_error);
}

TEST_F(SmallVocabulary, BatchLookupIsTheSameAsOneByOne) {
  std::vector<Descriptor> known;
  for (const auto& img : *images_) known.insert(known.end(), img.begin(), img.end());
  expect_batch_matches_one_by_one(*voc_, known);
}

TEST(DefaultVocabulary, BatchLookupIsTheSameAsOneByOne) {
  const Vocabulary voc = Vocabulary::load(default_vocabulary_path());
  OrbConfig oc;
  const OrbExtractor ex(oc);
  expect_batch_matches_one_by_one(voc, ex.extract(procedural_image(42)).descriptors);
}

TEST(DefaultVocabulary, LoadsAndHasTheDocumentedShape) {
  const std::string path = default_vocabulary_path();
  ASSERT_TRUE(std::filesystem::exists(path)) << path;
  const Vocabulary voc = Vocabulary::load(path);
  EXPECT_GE(voc.num_words(), 10000u);
  EXPECT_GE(voc.depth(), 4);
  EXPECT_EQ(voc.stats().zero_weight_words, 0u);
}

}  // namespace
}  // namespace cslam
