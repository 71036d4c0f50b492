#pragma once
// Feeds RGB-D pairs of a dataset to one client's SLAM, in order (offline runs, tests, benchmarks).
#include <vector>

#include "io/tum_dataset.h"
#include "slam/client_slam.h"

namespace cslam {

inline void feed_pairs(ClientSlam& slam, ClientId id, const std::vector<RgbdPair>& pairs) {
  for (const auto& p : pairs) {
    const auto im = load_rgbd(p);
    RgbdFrame f;
    f.client = id;
    f.timestamp = p.rgb_time;
    f.bgr = im.bgr;
    f.depth = im.depth;
    slam.process(f);
  }
}

}  // namespace cslam
