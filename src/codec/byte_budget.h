#pragma once
// A robot's byte budget (cslam-client --byte-budget): what its stream may send per second, spent
// on the full frames' colour. Keyframes come from full frames alone, and their colour sets what a
// lean stream's map is worth (docs/results/bandwidth.md: over 24 demo scenes JPEG q95 full frames
// bring the lean stream from 1.085x to 1.022x the default pair's ATE). A lean stream mostly sends
// less than a link share allows (light frames are ~10x smaller), so the sender gives each full
// frame's colour the finest of a few JPEG qualities its budget has room for, and the stream's own
// codec (standalone H.264 pictures) when none fits. The budget only ever makes a full frame's
// colour finer than the stream's codec, never coarser: a stream over it anyway (every frame full)
// is sent as without it.
//
// The room is a token bucket counted in frames, not time: every frame earns bytes_per_s /
// frame_rate bytes (the stream's nominal rate), the bucket holds at most burst_s seconds of them,
// and every frame sent spends its bytes. It starts empty, so a stream saves up only by sending
// less than the budget. Frames never wait for room: a light frame after a full frame that spent
// the bucket leaves it briefly negative, and the next full frames pay that back. So over any run
// of N frames the stream sends at most N frames' budget plus what it owes at the end (less than
// the light frames since the last full frame). The choice depends only on the bytes sent before:
// the C++ and Python senders send the same bytes, and the offline simulation makes the same
// choices from its own byte counts. A frame rate below the nominal (live frames dropped) only
// leaves more room per second.
#include <cstddef>
#include <vector>

namespace cslam {

struct ByteBudgetConfig {
  double bytes_per_s = 0;  // 0: no budget (the full frames' colour is the stream's codec)
  double frame_rate = 30;  // the stream's nominal frames per second
  double burst_s = 2.0;    // the bucket holds at most this many seconds of budget
  // The full frames' JPEG qualities the budget may choose, finest first (only those finer than
  // the stream's own JPEG quality when that is JPEG). q85..q95 each closed the lean stream's gap
  // on the demo scenes; coarser ones did not beat the H.264 pictures.
  std::vector<int> jpeg_qualities = {95, 90, 85};
  // Throws ConfigError on a negative or non-finite budget, a frame rate or burst outside
  // 0 < x <= 1000, or qualities not in 1..100 and strictly decreasing.
  void validate() const;
};

class ByteBudget {
 public:
  explicit ByteBudget(ByteBudgetConfig config);  // validates
  bool enabled() const { return config_.bytes_per_s > 0; }
  // Bytes the next frame may take: the bucket with the frame's own share (0 when it owes).
  std::size_t allowance() const;
  // What one image of the next frame may take beside the frame's other image bytes and its
  // header (kHeaderBytes): allowance() less both, 0 when they do not fit.
  std::size_t image_allowance(std::size_t other_image_bytes) const;
  // Every frame sent, in order: its bytes as counted against the budget (the sender: the wire
  // message's; the offline simulation: its images' plus kHeaderBytes).
  void add(std::size_t bytes);
  const ByteBudgetConfig& config() const { return config_; }
  // A wire frame's bytes beside its images (ids, times, sizes, encodings: 40-50 B), rounded up.
  static constexpr std::size_t kHeaderBytes = 64;

 private:
  double filled() const;  // the bucket with the next frame's share, at most its capacity

  ByteBudgetConfig config_;
  double share_ = 0;     // bytes a frame earns
  double capacity_ = 0;  // bytes the bucket holds at most
  double bucket_ = 0;    // bytes in the bucket now (negative: owed)
};

}  // namespace cslam
