#pragma once
// A hierarchical bag-of-words vocabulary over 256-bit ORB descriptors (DBoW2-style): a tree of
// k-majority cluster centres (k-means++ seeding), words at the leaves with TF-IDF weights,
// L1-normalised BoW vectors, DBoW2's L1 score and a direct index (feature vector) at a chosen level.
//
// File format (little-endian), version 1:
//   "CSLAMVOC" | u32 version | u32 branching | u32 depth | u32 num_nodes | u32 num_words
//   | u64 payload_bytes | u64 FNV-1a-64 checksum of the payload | payload
//   payload = u8 num_children[num_nodes] (breadth-first order, node 0 = root, children contiguous)
//           | 32-byte descriptors of nodes 1..num_nodes-1 | f32 weights[num_words]
//   Words are the leaves in node order.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "slam/bow/bow_vector.h"
#include "slam/features/descriptor.h"

namespace cslam {

struct VocabularyTrainConfig {
  int branching = 10;
  int depth = 6;
  int max_iterations = 10;
  int threads = 2;
  std::uint64_t seed = 1;
};

// Shape and statistics of a vocabulary (cslam-vocab info).
struct VocabularyStats {
  int branching = 0, depth = 0;
  std::size_t num_nodes = 0, num_words = 0;
  std::vector<std::size_t> words_per_level;  // leaves at each depth (index 0 = root)
  double mean_word_depth = 0;
  double min_weight = 0, max_weight = 0, mean_weight = 0;
  std::size_t zero_weight_words = 0;
};

class Vocabulary {
 public:
  Vocabulary() = default;

  // Throws InputError(path, ...) on missing/corrupt/truncated/wrong version/checksum.
  static Vocabulary load(const std::string& path);
  // Throws InputError(path, ...) if the file cannot be written (written atomically: temp + rename).
  void save(const std::string& path) const;

  // Hierarchical k-majority clustering of all descriptors; idf = log(N_images / images containing
  // the word). Throws ConfigError on branching outside [2,255], depth outside [1,10], no descriptors.
  static Vocabulary train(const std::vector<std::vector<Descriptor>>& descriptors_per_image,
                          const VocabularyTrainConfig& config);
  // Progress callback variant: called with (level, total levels) as each level is finished.
  static Vocabulary train(const std::vector<std::vector<Descriptor>>& descriptors_per_image,
                          const VocabularyTrainConfig& config, const std::function<void(int, int)>& progress);

  // levels_up: the direct-index level counted from the leaves (ORB-SLAM2 uses 4 with L=6).
  // Features whose word has zero weight are left out of both outputs (as DBoW2).
  void transform(const std::vector<Descriptor>& descriptors, BowVector& bow, FeatureVector& features,
                 int levels_up) const;
  void transform(const std::vector<Descriptor>& descriptors, BowVector& bow) const;
  WordId word_of(const Descriptor& d) const;
  // Word and the node at depth (depth() - levels_up) on its path (the leaf if it is shallower).
  WordId word_of(const Descriptor& d, int levels_up, NodeId& node) const;
  // word_of(d[i], levels_up, nodes[i]) into words[i] for i < n, the same results, faster for many.
  void words_of(const Descriptor* d, std::size_t n, int levels_up, WordId* words, NodeId* nodes) const;

  // DBoW2 L1 score: 1 - 0.5 * |a - b|_1 for L1-normalised vectors, in [0,1].
  static double score(const BowVector& a, const BowVector& b);

  int branching() const { return branching_; }
  int depth() const { return depth_; }
  std::size_t num_words() const { return word_node_.size(); }
  std::size_t num_nodes() const { return num_children_.size(); }
  bool empty() const { return word_node_.empty(); }
  double word_weight(WordId w) const { return weight_.at(w); }
  const Descriptor& word_descriptor(WordId w) const { return descriptor_.at(word_node_.at(w)); }
  VocabularyStats stats() const;

  bool operator==(const Vocabulary& o) const;
  bool operator!=(const Vocabulary& o) const { return !(*this == o); }

 private:
  friend class VocabularyBuilder;
  // The child of inner node `id` nearest to `d` (the first of equally near ones).
  std::uint32_t nearest_child(const Descriptor& d, std::uint32_t id) const;
  // Derives first_child_, level_, node_word_ and word_node_ from num_children_ (breadth-first).
  // Returns an error message, empty if the tree is consistent.
  std::string index_tree();

  int branching_ = 0, depth_ = 0;
  std::vector<std::uint8_t> num_children_;
  std::vector<Descriptor> descriptor_;  // per node (root: zeros)
  std::vector<float> weight_;           // per word
  // Derived.
  std::vector<std::uint32_t> first_child_;
  std::vector<std::uint8_t> level_;
  std::vector<WordId> node_word_;  // kNoWord for inner nodes
  std::vector<NodeId> word_node_;
};

// Path of the committed default vocabulary: env CSLAM_VOCABULARY if set, else the file under
// data/vocabulary/ of the source tree.
std::string default_vocabulary_path();

}  // namespace cslam
