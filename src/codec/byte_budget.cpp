#include "codec/byte_budget.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.h"

namespace cslam {

void ByteBudgetConfig::validate() const {
  if (!(bytes_per_s >= 0) || !std::isfinite(bytes_per_s))
    throw ConfigError("byte budget " + std::to_string(bytes_per_s) + " B/s must be >= 0 (0: none)");
  if (!(frame_rate > 0 && frame_rate <= 1000))
    throw ConfigError("byte budget frame rate " + std::to_string(frame_rate) + " must be in (0, 1000]");
  if (!(burst_s > 0 && burst_s <= 1000))
    throw ConfigError("byte budget burst " + std::to_string(burst_s) + " s must be in (0, 1000]");
  for (std::size_t i = 0; i < jpeg_qualities.size(); ++i) {
    const int q = jpeg_qualities[i];
    if (q < 1 || q > 100) throw ConfigError("byte budget JPEG quality " + std::to_string(q) + " not in 1..100");
    if (i > 0 && q >= jpeg_qualities[i - 1])
      throw ConfigError("byte budget JPEG qualities must be strictly decreasing (finest first)");
  }
}

ByteBudget::ByteBudget(ByteBudgetConfig config) : config_(std::move(config)) {
  config_.validate();
  share_ = config_.bytes_per_s / config_.frame_rate;
  capacity_ = std::max(share_, config_.bytes_per_s * config_.burst_s);
}

double ByteBudget::filled() const { return std::min(capacity_, bucket_ + share_); }

std::size_t ByteBudget::allowance() const {
  const double room = filled();
  return room > 0 ? std::size_t(room) : 0;
}

std::size_t ByteBudget::image_allowance(std::size_t other_image_bytes) const {
  const std::size_t taken = other_image_bytes + kHeaderBytes;
  const std::size_t all = allowance();
  return all > taken ? all - taken : 0;
}

void ByteBudget::add(std::size_t bytes) { bucket_ = filled() - double(bytes); }

}  // namespace cslam
