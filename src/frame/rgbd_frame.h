#pragma once
// The unit of input to the SLAM system: one registered RGB-D image pair from one client.
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

#include <opencv2/core.hpp>

#include "codec/encoded_rgbd.h"
#include "core/ids.h"
#include "geometry/camera.h"

namespace cslam {

struct ClientInfo {
  ClientId id = 0;
  std::string name;
  PinholeCamera camera;
};

// A depth image further than this from its colour image (seconds) is not one frame's pair.
inline constexpr double kMaxDepthTimeOffset = 0.1;

struct RgbdFrame {
  ClientId client = 0;
  std::uint64_t seq = 0;  // sender's sequence number
  double timestamp = 0;   // seconds, when the colour image was captured
  // When the depth image was captured, relative to the colour image (seconds; 0: together).
  // With RgbdParams::depth_time_compensation, tracking reads each keypoint's depth where the
  // camera's predicted motion over this gap carried it.
  double depth_time_offset = 0;  // |offset| <= kMaxDepthTimeOffset, else the frame is rejected
  cv::Mat bgr;                   // CV_8UC3
  cv::Mat depth;                 // CV_16UC1, raw units (camera.depth_factor per metre)
  // 1: the depth image as the camera took it. S > 1: every S-th pixel of every S-th row was sent
  // and `depth` holds them spread back to full size (each sample over its S x S block): good for
  // tracking, not for a keyframe (the map and the dense model need every pixel).
  int depth_subsample = 1;
  // Full depth: the frame may become a keyframe (a light frame of a lean stream may not).
  bool keyframe_eligible() const { return !depth.empty() && depth_subsample == 1; }
  // Live stream: the worker may skip this frame when a newer one of the client is already queued.
  bool live = false;
  // When the system got the frame (stamped by submit() if left at the epoch); pose latency.
  std::chrono::steady_clock::time_point received{};
  // When the server read the frame's packet, before decoding it (the epoch offline): the decoding
  // part of the pose latency's breakdown.
  std::chrono::steady_clock::time_point arrived{};
  // The images as the robot sent them (the server's frames; null offline): what the keyframe
  // store keeps, so the dense map is built from the received bytes, never a re-encoding.
  std::shared_ptr<const EncodedRgbd> encoded;
};

}  // namespace cslam
