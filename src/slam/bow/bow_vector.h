#pragma once
// Bag-of-words types shared by the vocabulary, the keyframe database and BoW-accelerated matching.
// Header-only so that features/matching.h can use them without linking cslam_bow.
#include <cstdint>
#include <vector>

#include <boost/container/flat_map.hpp>

namespace cslam {

using WordId = std::uint32_t;
using NodeId = std::uint32_t;

// Word -> L1-normalised tf-idf weight. Sorted vectors, not trees: every use walks two of them in
// word order (scores, BoW matching) or looks words up, and a frame's are built once.
using BowVector = boost::container::flat_map<WordId, double>;
// Vocabulary node at the direct-index level -> indices of the features under it (ascending).
using FeatureVector = boost::container::flat_map<NodeId, std::vector<int>>;

}  // namespace cslam
