// Vocabulary training: hierarchical k-majority clustering, level by level (breadth first, so node
// ids come out in the file's order), then idf weights from the training images.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <thread>

#include "slam/bow/kmajority.h"
#include "slam/bow/vocabulary.h"
#include "core/error.h"

namespace cslam {

class VocabularyBuilder {
 public:
  static Vocabulary train(const std::vector<std::vector<Descriptor>>& images, const VocabularyTrainConfig& config,
                          const std::function<void(int, int)>& progress);
};

namespace {

struct Task {
  std::uint32_t node;
  std::vector<std::uint32_t> members;
};

// Runs fn(i) for i in [0, n) on `threads` threads (dynamic scheduling).
void parallel_for(std::size_t n, int threads, const std::function<void(std::size_t)>& fn) {
  if (threads <= 1 || n <= 1) {
    for (std::size_t i = 0; i < n; ++i) fn(i);
    return;
  }
  std::atomic<std::size_t> next{0};
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&] {
      for (std::size_t i = next++; i < n; i = next++) fn(i);
    });
  for (std::thread& th : pool) th.join();
}

std::uint64_t mix_seed(std::uint64_t seed, std::uint64_t node) {
  std::uint64_t z = seed * 0x9E3779B97F4A7C15ull + node + 0x632BE59BD9B4E019ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

}  // namespace

Vocabulary VocabularyBuilder::train(const std::vector<std::vector<Descriptor>>& images,
                                    const VocabularyTrainConfig& config,
                                    const std::function<void(int, int)>& progress) {
  if (config.branching < 2 || config.branching > 255)
    throw ConfigError("VocabularyTrainConfig.branching must be in [2,255]");
  if (config.depth < 1 || config.depth > 10) throw ConfigError("VocabularyTrainConfig.depth must be in [1,10]");
  if (config.max_iterations < 1) throw ConfigError("VocabularyTrainConfig.max_iterations must be >= 1");
  const int threads = std::max(1, config.threads);

  std::vector<Descriptor> all;
  for (const auto& img : images) all.insert(all.end(), img.begin(), img.end());
  if (all.empty()) throw ConfigError("Vocabulary::train: no training descriptors");

  Vocabulary v;
  v.branching_ = config.branching;
  v.depth_ = config.depth;
  v.num_children_.push_back(0);
  v.descriptor_.push_back(Descriptor{0, 0, 0, 0});

  std::vector<Task> level_tasks(1);
  level_tasks[0].node = 0;
  level_tasks[0].members.resize(all.size());
  for (std::uint32_t i = 0; i < all.size(); ++i) level_tasks[0].members[i] = i;

  for (int level = 0; level < config.depth && !level_tasks.empty(); ++level) {
    // Cluster every node of this level: big ones one at a time with a parallel assignment,
    // the many small ones in parallel.
    std::vector<KMajorityResult> results(level_tasks.size());
    auto cluster = [&](std::size_t t, int inner_threads) {
      const Task& task = level_tasks[t];
      KMajorityResult& r = results[t];
      if (int(task.members.size()) <= config.branching) {
        for (std::uint32_t m : task.members) {  // each descriptor becomes its own child (DBoW2)
          r.centers.push_back(all[m]);
          r.clusters.push_back({m});
        }
        return;
      }
      r = kmajority(all, task.members, config.branching, config.max_iterations, mix_seed(config.seed, task.node),
                    inner_threads);
    };
    std::vector<std::size_t> small;
    for (std::size_t t = 0; t < level_tasks.size(); ++t) {
      if (level_tasks[t].members.size() > 50000)
        cluster(t, threads);
      else
        small.push_back(t);
    }
    parallel_for(small.size(), threads, [&](std::size_t i) { cluster(small[i], 1); });

    // Append children in breadth-first order and queue the ones that can be split further.
    std::vector<Task> next;
    for (std::size_t t = 0; t < level_tasks.size(); ++t) {
      KMajorityResult& r = results[t];
      // A single cluster holding every member (identical descriptors) ends the branch.
      if (r.centers.size() <= 1 && level > 0) continue;
      v.num_children_[level_tasks[t].node] = std::uint8_t(r.centers.size());
      for (std::size_t c = 0; c < r.centers.size(); ++c) {
        const std::uint32_t id = std::uint32_t(v.num_children_.size());
        v.num_children_.push_back(0);
        v.descriptor_.push_back(r.centers[c]);
        if (level + 1 < config.depth && r.clusters[c].size() > 1) next.push_back({id, std::move(r.clusters[c])});
      }
    }
    level_tasks.swap(next);
    if (progress) progress(level + 1, config.depth);
  }

  const std::string err = v.index_tree();
  if (!err.empty()) throw std::logic_error("Vocabulary::train produced an inconsistent tree: " + err);

  // idf = log(N / n_i), n_i = number of training images containing word i.
  std::vector<std::uint32_t> image_count(v.num_words(), 0);
  std::vector<std::vector<WordId>> words_per_image(images.size());
  parallel_for(images.size(), threads, [&](std::size_t i) {
    auto& words = words_per_image[i];
    for (const Descriptor& d : images[i]) words.push_back(v.word_of(d));
    std::sort(words.begin(), words.end());
    words.erase(std::unique(words.begin(), words.end()), words.end());
  });
  for (const auto& words : words_per_image)
    for (WordId w : words) ++image_count[w];
  const double n_images = double(images.size());
  v.weight_.resize(v.num_words());
  for (std::size_t w = 0; w < v.num_words(); ++w)
    v.weight_[w] = image_count[w] > 0 ? float(std::log(n_images / image_count[w])) : 0.0f;
  return v;
}

Vocabulary Vocabulary::train(const std::vector<std::vector<Descriptor>>& descriptors_per_image,
                             const VocabularyTrainConfig& config) {
  return VocabularyBuilder::train(descriptors_per_image, config, nullptr);
}

Vocabulary Vocabulary::train(const std::vector<std::vector<Descriptor>>& descriptors_per_image,
                             const VocabularyTrainConfig& config, const std::function<void(int, int)>& progress) {
  return VocabularyBuilder::train(descriptors_per_image, config, progress);
}

}  // namespace cslam
