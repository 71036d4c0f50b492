#pragma once
// Which of a client's maps its trajectory covers: maps with equal frame labels share a frame
// (map fusion's group; a negative label is a frame of its own). The frame holding most tracked
// frames wins; on a tie, the one holding the lowest map index. One rule for the live state
// (ClientSlam::trajectory) and a snapshot's (state_trajectory).
#include <cstddef>
#include <vector>

namespace cslam {

// frames_per_map[i]: tracked frames in map i; labels[i]: its frame label. Returns a flag per map.
inline std::vector<char> maps_in_main_frame(const std::vector<std::size_t>& frames_per_map, std::vector<long> labels) {
  const std::size_t n = frames_per_map.size();
  for (std::size_t i = 0; i < n; ++i)
    if (labels[i] < 0) labels[i] = -1 - long(i);
  std::size_t best = 0, best_frames = 0;
  for (std::size_t i = 0; i < n; ++i) {
    std::size_t frames = 0;
    for (std::size_t j = 0; j < n; ++j)
      if (labels[j] == labels[i]) frames += frames_per_map[j];
    if (frames > best_frames) best = i, best_frames = frames;
  }
  std::vector<char> in(n, 0);
  for (std::size_t i = 0; i < n; ++i) in[i] = n > 0 && labels[i] == labels[best];
  return in;
}

}  // namespace cslam
