#pragma once
// Feeds RGB-D pairs of a dataset to one client's SLAM, in order (offline runs, tests, benchmarks).
#include <vector>

#include "io/tum_dataset.h"
#include "slam/client_slam.h"

namespace cslam {

// The pair's images as client `id`'s frame, stamped with the colour image's time.
inline RgbdFrame load_rgbd_frame(const RgbdPair& p, ClientId id) {
  const auto im = load_rgbd(p);
  RgbdFrame f;
  f.client = id;
  f.timestamp = p.rgb_time;
  f.bgr = im.bgr;
  f.depth = im.depth;
  return f;
}

inline void feed_pairs(ClientSlam& slam, ClientId id, const std::vector<RgbdPair>& pairs) {
  for (const auto& p : pairs) slam.process(load_rgbd_frame(p, id));
}

}  // namespace cslam
