#pragma once
// A dataset's RGB-D pair as one client's frame (offline runs, replay clients, tests, benchmarks).
#include <cstdint>
#include <utility>

#include "io/tum_dataset.h"
#include "frame/rgbd_frame.h"

namespace cslam {

// Stamped with the colour image's time; the depth image's time is kept as its offset from it.
inline RgbdFrame dataset_frame(const RgbdPair& p, RgbdImages images, ClientId id, std::uint64_t seq = 0) {
  RgbdFrame f;
  f.client = id;
  f.seq = seq;
  f.timestamp = p.rgb_time;
  f.depth_time_offset = p.depth_time - p.rgb_time;
  f.bgr = std::move(images.bgr);
  f.depth = std::move(images.depth);
  return f;
}

inline RgbdFrame load_dataset_frame(const RgbdPair& p, ClientId id, std::uint64_t seq = 0) {
  return dataset_frame(p, load_rgbd(p), id, seq);
}

}  // namespace cslam
