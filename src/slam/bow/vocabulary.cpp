#include "slam/bow/vocabulary.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <stdexcept>

#include "core/error.h"

namespace cslam {

namespace {

constexpr char kMagic[8] = {'C', 'S', 'L', 'A', 'M', 'V', 'O', 'C'};
constexpr std::uint32_t kVersion = 1;
constexpr WordId kNoWord = std::numeric_limits<WordId>::max();
constexpr std::size_t kHeaderBytes = 8 + 5 * 4 + 8 + 8;

std::uint64_t fnv1a64(const std::uint8_t* data, std::size_t n) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (std::size_t i = 0; i < n; ++i) {
    h ^= data[i];
    h *= 0x100000001b3ull;
  }
  return h;
}

template <typename T>
void put(std::vector<std::uint8_t>& buf, const T& v) {
  const auto* p = reinterpret_cast<const std::uint8_t*>(&v);
  buf.insert(buf.end(), p, p + sizeof(T));
}

template <typename T>
T get(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

}  // namespace

std::string Vocabulary::index_tree() {
  const std::size_t n = num_children_.size();
  first_child_.assign(n, 0);
  level_.assign(n, 0);
  node_word_.assign(n, kNoWord);
  word_node_.clear();
  if (n == 0) return "no nodes";
  std::size_t next = 1;
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0 && i >= next) return "node " + std::to_string(i) + " has no parent";
    first_child_[i] = std::uint32_t(next);
    if (num_children_[i] > branching_)
      return "node " + std::to_string(i) + " has more children than the branching factor";
    if (num_children_[i] == 0) {
      if (i == 0) return "the root has no children";
      node_word_[i] = WordId(word_node_.size());
      word_node_.push_back(NodeId(i));
      continue;
    }
    if (level_[i] >= depth_) return "node " + std::to_string(i) + " is deeper than the tree depth";
    if (next + num_children_[i] > n) return "children of node " + std::to_string(i) + " exceed the node count";
    for (std::size_t c = next; c < next + num_children_[i]; ++c) level_[c] = std::uint8_t(level_[i] + 1);
    next += num_children_[i];
  }
  if (next != n) return "node count does not match the children counts";
  return "";
}

Vocabulary Vocabulary::load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open vocabulary file");
  std::vector<std::uint8_t> buf((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (buf.size() < kHeaderBytes)
    throw InputError(path, "truncated vocabulary file (" + std::to_string(buf.size()) + " bytes, header needs " +
                               std::to_string(kHeaderBytes) + ")");
  if (std::memcmp(buf.data(), kMagic, 8) != 0) throw InputError(path, "not a cslam vocabulary file (bad magic)");
  const std::uint8_t* p = buf.data() + 8;
  const auto version = get<std::uint32_t>(p);
  if (version != kVersion)
    throw InputError(path, "unsupported vocabulary version " + std::to_string(version) + " (expected " +
                               std::to_string(kVersion) + ")");
  Vocabulary v;
  const auto k = get<std::uint32_t>(p + 4), L = get<std::uint32_t>(p + 8);
  const auto num_nodes = get<std::uint32_t>(p + 12), num_words = get<std::uint32_t>(p + 16);
  const auto payload = get<std::uint64_t>(p + 20), checksum = get<std::uint64_t>(p + 28);
  if (k < 2 || k > 255 || L < 1 || L > 10 || num_nodes < 2 || num_words < 1 || num_words >= num_nodes)
    throw InputError(path, "corrupt vocabulary header (k=" + std::to_string(k) + " L=" + std::to_string(L) +
                               " nodes=" + std::to_string(num_nodes) + " words=" + std::to_string(num_words) + ")");
  const std::uint64_t expected = std::uint64_t(num_nodes) + 32ull * (num_nodes - 1) + 4ull * num_words;
  if (payload != expected)
    throw InputError(path, "corrupt vocabulary header (payload size does not match the node count)");
  if (buf.size() - kHeaderBytes < payload)
    throw InputError(path, "truncated vocabulary file (" + std::to_string(buf.size()) + " bytes, expected " +
                               std::to_string(kHeaderBytes + payload) + ")");
  if (buf.size() - kHeaderBytes > payload) throw InputError(path, "trailing bytes after the vocabulary payload");
  const std::uint8_t* data = buf.data() + kHeaderBytes;
  if (fnv1a64(data, payload) != checksum) throw InputError(path, "vocabulary checksum mismatch (file corrupt)");

  v.branching_ = int(k);
  v.depth_ = int(L);
  v.num_children_.assign(data, data + num_nodes);
  v.descriptor_.resize(num_nodes);
  v.descriptor_[0].fill(0);
  std::memcpy(v.descriptor_.data() + 1, data + num_nodes, 32ull * (num_nodes - 1));
  v.weight_.resize(num_words);
  std::memcpy(v.weight_.data(), data + num_nodes + 32ull * (num_nodes - 1), 4ull * num_words);
  const std::string err = v.index_tree();
  if (!err.empty()) throw InputError(path, "corrupt vocabulary tree: " + err);
  if (v.word_node_.size() != num_words)
    throw InputError(path, "corrupt vocabulary: leaf count differs from the word count");
  for (float w : v.weight_)
    if (!std::isfinite(w) || w < 0) throw InputError(path, "corrupt vocabulary: invalid word weight");
  return v;
}

void Vocabulary::save(const std::string& path) const {
  if (empty()) throw std::logic_error("Vocabulary::save: empty vocabulary");
  std::vector<std::uint8_t> payload;
  payload.reserve(num_nodes() * 33 + num_words() * 4);
  payload.insert(payload.end(), num_children_.begin(), num_children_.end());
  for (std::size_t i = 1; i < descriptor_.size(); ++i) {
    const auto* d = reinterpret_cast<const std::uint8_t*>(descriptor_[i].data());
    payload.insert(payload.end(), d, d + 32);
  }
  for (float w : weight_) put(payload, w);
  std::vector<std::uint8_t> header(kMagic, kMagic + 8);
  put(header, kVersion);
  put(header, std::uint32_t(branching_));
  put(header, std::uint32_t(depth_));
  put(header, std::uint32_t(num_nodes()));
  put(header, std::uint32_t(num_words()));
  put(header, std::uint64_t(payload.size()));
  put(header, fnv1a64(payload.data(), payload.size()));

  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw InputError(path, "cannot write vocabulary file");
    out.write(reinterpret_cast<const char*>(header.data()), std::streamsize(header.size()));
    out.write(reinterpret_cast<const char*>(payload.data()), std::streamsize(payload.size()));
    if (!out) throw InputError(path, "error while writing vocabulary file");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw InputError(path, "cannot rename the temporary vocabulary file into place");
  }
}

std::uint32_t Vocabulary::nearest_child(const Descriptor& d, std::uint32_t id) const {
  const std::uint32_t first = first_child_[id], last = first + num_children_[id];
  std::uint32_t best = first;
  int best_dist = hamming_distance(d, descriptor_[first]);
  for (std::uint32_t c = first + 1; c < last; ++c) {
    const int dist = hamming_distance(d, descriptor_[c]);
    if (dist < best_dist) {
      best_dist = dist;
      best = c;
    }
  }
  return best;
}

WordId Vocabulary::word_of(const Descriptor& d, int levels_up, NodeId& node) const {
  if (num_children_.empty()) throw std::logic_error("Vocabulary::word_of: empty vocabulary");
  const int target = depth_ - levels_up;
  std::uint32_t id = 0;
  node = 0;
  while (num_children_[id] > 0) {
    id = nearest_child(d, id);
    if (level_[id] <= target) node = id;
  }
  if (target > level_[id]) node = id;
  return node_word_[id];
}

void Vocabulary::words_of(const Descriptor* d, std::size_t n, int levels_up, WordId* words, NodeId* nodes) const {
  if (num_children_.empty()) throw std::logic_error("Vocabulary::words_of: empty vocabulary");
  // word_of for a batch of descriptors in lock-step, one tree level at a time: the deep levels'
  // child groups (3.2 MB at the leaves) are mostly cache misses, and each descriptor's next group
  // is prefetched while the batch's other descriptors are compared, so that the misses overlap.
  const int target = depth_ - levels_up;
  constexpr std::size_t kBatch = 16;
  for (std::size_t start = 0; start < n; start += kBatch) {
    const std::size_t m = std::min(kBatch, n - start);
    std::uint32_t id[kBatch] = {};
    std::size_t active = m;
    for (std::size_t k = 0; k < m; ++k) nodes[start + k] = 0;
    while (active > 0) {
      active = 0;
      for (std::size_t k = 0; k < m; ++k) {
        if (num_children_[id[k]] == 0) continue;
        const std::uint32_t best = nearest_child(d[start + k], id[k]);
        id[k] = best;
        if (level_[best] <= target) nodes[start + k] = best;
        if (num_children_[best] == 0) continue;
        ++active;
        // The next level's children, and what picking one of them reads.
        const std::uint32_t next = first_child_[best];
        const char* group = reinterpret_cast<const char*>(&descriptor_[next]);
        for (std::size_t b = 0; b < num_children_[best] * sizeof(Descriptor); b += 64) __builtin_prefetch(group + b);
        __builtin_prefetch(&first_child_[next]);
        __builtin_prefetch(&num_children_[next]);
        __builtin_prefetch(&level_[next]);
      }
    }
    for (std::size_t k = 0; k < m; ++k) {
      if (target > level_[id[k]]) nodes[start + k] = id[k];
      words[start + k] = node_word_[id[k]];
    }
  }
}

WordId Vocabulary::word_of(const Descriptor& d) const {
  NodeId unused;
  return word_of(d, 0, unused);
}

namespace {

// Sums (word, weight) pairs per word, in the order they were added (the sums equal adding them
// one by one into a map), then L1-normalises.
void build_bow(std::vector<std::pair<WordId, double>>& words, BowVector& bow) {
  std::stable_sort(words.begin(), words.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  BowVector::sequence_type seq;
  seq.reserve(words.size());
  for (const auto& [w, v] : words) {
    if (!seq.empty() && seq.back().first == w)
      seq.back().second += v;
    else
      seq.emplace_back(w, v);
  }
  double sum = 0;
  for (const auto& [w, v] : seq) sum += v;
  if (sum > 0)
    for (auto& [w, v] : seq) v /= sum;
  bow.adopt_sequence(boost::container::ordered_unique_range, std::move(seq));
}

}  // namespace

void Vocabulary::transform(const std::vector<Descriptor>& descriptors, BowVector& bow, FeatureVector& features,
                           int levels_up) const {
  bow.clear();
  features.clear();
  if (empty()) return;
  std::vector<std::pair<WordId, double>> words;
  std::vector<std::pair<NodeId, int>> nodes;
  words.reserve(descriptors.size());
  nodes.reserve(descriptors.size());
  std::vector<WordId> word(descriptors.size());
  std::vector<NodeId> node(descriptors.size());
  words_of(descriptors.data(), descriptors.size(), levels_up, word.data(), node.data());
  for (std::size_t i = 0; i < descriptors.size(); ++i) {
    const double weight = weight_[word[i]];
    if (weight <= 0) continue;
    words.emplace_back(word[i], weight);
    nodes.emplace_back(node[i], int(i));
  }
  build_bow(words, bow);
  std::stable_sort(nodes.begin(), nodes.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  FeatureVector::sequence_type seq;
  for (const auto& [node, i] : nodes) {
    if (seq.empty() || seq.back().first != node) seq.emplace_back(node, std::vector<int>{});
    seq.back().second.push_back(i);
  }
  features.adopt_sequence(boost::container::ordered_unique_range, std::move(seq));
}

void Vocabulary::transform(const std::vector<Descriptor>& descriptors, BowVector& bow) const {
  bow.clear();
  if (empty()) return;
  std::vector<std::pair<WordId, double>> words;
  words.reserve(descriptors.size());
  std::vector<WordId> word(descriptors.size());
  std::vector<NodeId> node(descriptors.size());
  words_of(descriptors.data(), descriptors.size(), 0, word.data(), node.data());
  for (const WordId w : word)
    if (weight_[w] > 0) words.emplace_back(w, weight_[w]);
  build_bow(words, bow);
}

double Vocabulary::score(const BowVector& a, const BowVector& b) {
  // For L1-normalised vectors |a-b|_1 = 2 - sum over common words of (|ai| + |bi| - |ai - bi|).
  // A linear merge of the two sorted word lists: BoW vectors of similar size share many words,
  // so stepping is cheaper than a binary search (over the whole vector) at every mismatch.
  double common = 0;
  auto ia = a.begin(), ib = b.begin();
  const auto ea = a.end(), eb = b.end();
  // Without branches (which list steps is as good as random): a word not in both adds term * 0,
  // an exact +0 (the terms are finite and >= 0), so the sum is the branching loop's.
  while (ia != ea && ib != eb) {
    const auto wa = ia->first, wb = ib->first;
    const double term = std::abs(ia->second) + std::abs(ib->second) - std::abs(ia->second - ib->second);
    common += term * double(wa == wb);
    ia += std::ptrdiff_t(wa <= wb);
    ib += std::ptrdiff_t(wb <= wa);
  }
  return 0.5 * common;
}

VocabularyStats Vocabulary::stats() const {
  VocabularyStats s;
  s.branching = branching_;
  s.depth = depth_;
  s.num_nodes = num_nodes();
  s.num_words = num_words();
  s.words_per_level.assign(depth_ + 1, 0);
  double depth_sum = 0, wsum = 0;
  s.min_weight = weight_.empty() ? 0 : weight_[0];
  s.max_weight = s.min_weight;
  for (std::size_t w = 0; w < word_node_.size(); ++w) {
    const int l = level_[word_node_[w]];
    ++s.words_per_level[l];
    depth_sum += l;
    s.min_weight = std::min<double>(s.min_weight, weight_[w]);
    s.max_weight = std::max<double>(s.max_weight, weight_[w]);
    wsum += weight_[w];
    s.zero_weight_words += weight_[w] <= 0;
  }
  if (!word_node_.empty()) {
    s.mean_word_depth = depth_sum / word_node_.size();
    s.mean_weight = wsum / word_node_.size();
  }
  return s;
}

bool Vocabulary::operator==(const Vocabulary& o) const {
  return branching_ == o.branching_ && depth_ == o.depth_ && num_children_ == o.num_children_ &&
         descriptor_ == o.descriptor_ && weight_ == o.weight_;
}

std::string default_vocabulary_path() {
  if (const char* env = std::getenv("CSLAM_VOCABULARY"); env && *env) return env;
  return CSLAM_DEFAULT_VOCABULARY_PATH;
}

}  // namespace cslam
