#pragma once
// Bag-of-words types shared by the vocabulary, the keyframe database and BoW-accelerated matching.
// Header-only so that features/matching.h can use them without linking cslam_bow.
#include <cstdint>
#include <map>
#include <vector>

namespace cslam {

using WordId = std::uint32_t;
using NodeId = std::uint32_t;

// Word -> L1-normalised tf-idf weight.
using BowVector = std::map<WordId, double>;
// Vocabulary node at the direct-index level -> indices of the features under it (ascending).
using FeatureVector = std::map<NodeId, std::vector<int>>;

}  // namespace cslam
