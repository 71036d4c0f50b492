#pragma once
// k-majority clustering of binary descriptors (k-medians under the Hamming distance): k-means++
// seeding, nearest-centre assignment, per-bit majority update. Building block of the vocabulary.
#include <cstdint>
#include <vector>

#include "slam/features/descriptor.h"

namespace cslam {

// Majority of the given descriptors, bit by bit: a bit is set iff strictly more than half of the
// members have it set (ties -> 0). Empty input -> all zeros.
Descriptor majority_descriptor(const std::vector<Descriptor>& all, const std::vector<std::uint32_t>& members);

struct KMajorityResult {
  std::vector<Descriptor> centers;                   // non-empty clusters only
  std::vector<std::vector<std::uint32_t>> clusters;  // members of each centre (indices into `all`)
  int iterations = 0;
};

// Clusters all[members] into at most k groups. The final assignment is to the nearest final centre
// (first centre on ties), so descending a tree built from these centres sends every member to its
// own cluster. threads > 1 parallelises the assignment of large member sets.
KMajorityResult kmajority(const std::vector<Descriptor>& all, const std::vector<std::uint32_t>& members, int k,
                          int max_iterations, std::uint64_t seed, int threads = 1);

}  // namespace cslam
