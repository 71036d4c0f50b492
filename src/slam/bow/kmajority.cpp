#include "slam/bow/kmajority.h"

#include <algorithm>
#include <array>
#include <random>
#include <thread>

namespace cslam {

namespace {

// kByteLanes[v] holds bit i of byte v in byte lane i: adding it counts 8 bits at once (SWAR).
struct ByteLanes {
  std::array<std::uint64_t, 256> lanes{};
  ByteLanes() {
    for (int v = 0; v < 256; ++v)
      for (int i = 0; i < 8; ++i)
        if (v & (1 << i)) lanes[v] |= std::uint64_t(1) << (8 * i);
  }
};
const ByteLanes kByteLanes;

// Per-bit counter for a set of descriptors.
class BitCounter {
 public:
  void add(const Descriptor& d) {
    const auto* bytes = reinterpret_cast<const std::uint8_t*>(d.data());
    for (int j = 0; j < 32; ++j) acc_[j] += kByteLanes.lanes[bytes[j]];
    if (++pending_ == 255) flush();
    ++n_;
  }
  Descriptor majority() {
    flush();
    Descriptor out{0, 0, 0, 0};
    auto* bytes = reinterpret_cast<std::uint8_t*>(out.data());
    for (int bit = 0; bit < 256; ++bit)
      if (2 * std::uint64_t(counts_[bit]) > n_) bytes[bit >> 3] |= std::uint8_t(1u << (bit & 7));
    return out;
  }

 private:
  void flush() {
    for (int j = 0; j < 32; ++j) {
      for (int i = 0; i < 8; ++i) counts_[8 * j + i] += std::uint32_t((acc_[j] >> (8 * i)) & 0xff);
      acc_[j] = 0;
    }
    pending_ = 0;
  }
  std::array<std::uint64_t, 32> acc_{};
  std::array<std::uint32_t, 256> counts_{};
  int pending_ = 0;
  std::uint64_t n_ = 0;
};

int nearest(const Descriptor& d, const std::vector<Descriptor>& centers) {
  int best = 0, best_dist = hamming_distance(d, centers[0]);
  for (int c = 1; c < int(centers.size()); ++c) {
    const int dist = hamming_distance(d, centers[c]);
    if (dist < best_dist) {
      best_dist = dist;
      best = c;
    }
  }
  return best;
}

// Assigns every member to its nearest centre; returns the number of changed assignments.
std::size_t assign(const std::vector<Descriptor>& all, const std::vector<std::uint32_t>& members,
                   const std::vector<Descriptor>& centers, std::vector<int>& label, int threads) {
  const std::size_t n = members.size();
  auto work = [&](std::size_t begin, std::size_t end, std::size_t* changed) {
    std::size_t ch = 0;
    for (std::size_t i = begin; i < end; ++i) {
      const int c = nearest(all[members[i]], centers);
      ch += c != label[i];
      label[i] = c;
    }
    *changed = ch;
  };
  if (threads <= 1 || n < 20000) {
    std::size_t changed = 0;
    work(0, n, &changed);
    return changed;
  }
  std::vector<std::size_t> changed(threads, 0);
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) pool.emplace_back(work, n * t / threads, n * (t + 1) / threads, &changed[t]);
  for (std::thread& th : pool) th.join();
  std::size_t total = 0;
  for (std::size_t c : changed) total += c;
  return total;
}

}  // namespace

Descriptor majority_descriptor(const std::vector<Descriptor>& all, const std::vector<std::uint32_t>& members) {
  BitCounter counter;
  for (std::uint32_t m : members) counter.add(all[m]);
  return counter.majority();
}

KMajorityResult kmajority(const std::vector<Descriptor>& all, const std::vector<std::uint32_t>& members, int k,
                          int max_iterations, std::uint64_t seed, int threads) {
  KMajorityResult result;
  const std::size_t n = members.size();
  if (n == 0 || k < 1) return result;
  std::mt19937_64 rng(seed);

  // k-means++ seeding: next centre drawn with probability proportional to the squared distance.
  std::vector<Descriptor> centers;
  centers.push_back(all[members[std::uniform_int_distribution<std::size_t>(0, n - 1)(rng)]]);
  std::vector<double> d2(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double d = hamming_distance(all[members[i]], centers[0]);
    d2[i] = d * d;
  }
  while (int(centers.size()) < k) {
    double sum = 0;
    for (double v : d2) sum += v;
    if (sum <= 0) break;  // every member equals a centre already
    double r = std::uniform_real_distribution<double>(0, sum)(rng);
    std::size_t pick = 0;
    for (; pick + 1 < n; ++pick) {
      r -= d2[pick];
      if (r < 0) break;
    }
    while (d2[pick] <= 0 && pick > 0) --pick;  // guard against rounding landing on a zero
    centers.push_back(all[members[pick]]);
    for (std::size_t i = 0; i < n; ++i) {
      const double d = hamming_distance(all[members[i]], centers.back());
      d2[i] = std::min(d2[i], d * d);
    }
  }

  std::vector<int> label(n, -1);
  for (int it = 0; it < max_iterations; ++it) {
    const std::size_t changed = assign(all, members, centers, label, threads);
    ++result.iterations;
    if (changed == 0) break;
    std::vector<BitCounter> counters(centers.size());
    std::vector<std::size_t> sizes(centers.size(), 0);
    for (std::size_t i = 0; i < n; ++i) {
      counters[label[i]].add(all[members[i]]);
      ++sizes[label[i]];
    }
    for (std::size_t c = 0; c < centers.size(); ++c)
      if (sizes[c] > 0) centers[c] = counters[c].majority();  // an empty cluster keeps its centre
  }
  // Final assignment to the final centres (consistent with a nearest-centre descent).
  assign(all, members, centers, label, threads);

  std::vector<std::vector<std::uint32_t>> clusters(centers.size());
  for (std::size_t i = 0; i < n; ++i) clusters[label[i]].push_back(members[i]);
  for (std::size_t c = 0; c < centers.size(); ++c) {
    if (clusters[c].empty()) continue;
    result.centers.push_back(centers[c]);
    result.clusters.push_back(std::move(clusters[c]));
  }
  return result;
}

}  // namespace cslam
