#pragma once
// Feeds RGB-D pairs of a dataset to one client's SLAM, in order (offline runs, tests, benchmarks).
#include <vector>

#include "io/tum_dataset.h"
#include "slam/client_slam.h"
#include "io/dataset_frame.h"

namespace cslam {

inline void feed_pairs(ClientSlam& slam, ClientId id, const std::vector<RgbdPair>& pairs) {
  for (const auto& p : pairs) slam.process(load_dataset_frame(p, id));
}

}  // namespace cslam
