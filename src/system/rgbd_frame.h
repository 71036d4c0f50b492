#pragma once
// The unit of input to the SLAM system: one registered RGB-D image pair from one client.
#include <chrono>
#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

#include "core/ids.h"
#include "geometry/camera.h"

namespace cslam {

struct ClientInfo {
  ClientId id = 0;
  std::string name;
  PinholeCamera camera;
};

struct RgbdFrame {
  ClientId client = 0;
  std::uint64_t seq = 0;   // sender's sequence number
  double timestamp = 0;    // seconds
  cv::Mat bgr;             // CV_8UC3
  cv::Mat depth;           // CV_16UC1, raw units (camera.depth_factor per metre)
  // Live stream: the worker may skip this frame when a newer one of the client is already queued.
  bool live = false;
  // When the system got the frame (stamped by submit() if left at the epoch); pose latency.
  std::chrono::steady_clock::time_point received{};
};

}  // namespace cslam
