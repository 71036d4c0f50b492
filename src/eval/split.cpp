#include "eval/split.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/error.h"

namespace cslam {

SplitResult split_sequence(int n, int k, double eta) {
  if (k < 1) throw std::invalid_argument("split: need at least 1 client");
  if (n < k)
    throw std::invalid_argument("split: " + std::to_string(n) + " frames cannot be split into " + std::to_string(k) +
                                " clients");
  if (!(eta >= 0.0 && eta < 1.0))
    throw std::invalid_argument("split: overlap rate must be in [0, 1), e.g. 0.05 for 5%");
  const double N = n, K = k;
  const double L = N / K;
  SplitResult r;
  r.delta = k == 1 ? 0.0 : eta * L / (1.0 - eta * (K - 1.0) / K);
  for (int c = 1; c <= k; ++c) {
    double first = 1, last = N;
    if (c > 1) {
      const double b = (c - 1) * N / K;
      first = (k == 2) ? b - r.delta / 2.0 : b + 1.0 - (c - 1) * r.delta / K;
    }
    if (c < k) last = c * N / K + (K - c) * r.delta / K;
    FrameRange fr;
    fr.first = std::clamp(int(std::lround(first)), 1, n);
    fr.last = std::clamp(int(std::lround(last)), 1, n);
    r.ranges.push_back(fr);
  }
  return r;
}

double parse_overlap_rate(std::string text) {
  const bool percent = !text.empty() && text.back() == '%';
  if (percent) text.pop_back();
  size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (text.empty() || used != text.size()) throw ConfigError("overlap rate expects a number such as 0.05 or 5%");
  return percent ? v / 100.0 : v;
}

}  // namespace cslam
