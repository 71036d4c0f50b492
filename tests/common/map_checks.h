#pragma once
// Structural checks of a map for tests (caller holds the map's lock, shared at least): finite
// poses and points, keypoint <-> point links in both directions, symmetric covisibility.
#include <gtest/gtest.h>

#include "slam/map/map.h"

namespace cslam::test {

inline void expect_consistent(const Map& map) {
  for (const auto& kf : map.keyframes()) {
    EXPECT_TRUE(kf->T_cam_world.is_finite());
    for (size_t i = 0; i < kf->map_points.size(); ++i) {
      const auto& mp = kf->map_points[i];
      if (!mp || mp->bad) continue;
      EXPECT_TRUE(mp->position.allFinite());
      auto it = mp->observations.find(kf.get());
      ASSERT_NE(it, mp->observations.end()) << "point lists no observation back to its keyframe";
      EXPECT_EQ(it->second, int(i));
    }
    for (const auto& [other, w] : kf->connections) EXPECT_EQ(other->weight(kf.get()), w);
  }
}

}  // namespace cslam::test
