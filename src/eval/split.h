#pragma once
// The paper's split of one sequence of N frames into K clients with overlap rate eta.
#include <string>
#include <utility>
#include <vector>

namespace cslam {

struct FrameRange {
  int first = 1, last = 1;  // 1-based inclusive
  int count() const { return last - first + 1; }
};

struct SplitResult {
  double delta = 0;  // overlap length in frames between neighbours, delta = eta L / (1 - eta (K-1)/K)
  std::vector<FrameRange> ranges;
};

// With L = N/K and boundaries b_k = kN/K: client k (1-based) ends at b_k + (K-k) delta/K and
// client k+1 starts at b_k + 1 - k delta/K, so eta = delta / (L + (K-1) delta / K) for every
// client. For K = 2 the paper writes the second start as N/2 - delta/2 (no +1); we follow it.
// Values are rounded to the nearest frame. Throws std::invalid_argument if N < K, K < 1 or
// eta outside [0, 1).
SplitResult split_sequence(int num_frames, int clients, double overlap_rate);

// "0.05" or "5%" -> 0.05; throws ConfigError on anything else.
double parse_overlap_rate(std::string text);

}  // namespace cslam
