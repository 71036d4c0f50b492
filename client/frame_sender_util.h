#pragma once
// Helpers shared by the FrameSender source files (not part of the client library's interface).
#include <chrono>

#include "core/log.h"

namespace cslam::client::detail {

inline auto log() { return logger("client"); }

inline std::chrono::milliseconds to_ms(double seconds) { return std::chrono::milliseconds(long(seconds * 1000.0)); }

}  // namespace cslam::client::detail
