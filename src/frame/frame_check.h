#pragma once
// What makes an RgbdFrame well formed for its client's camera: the one definition. The boundary
// that builds frames checks it once (proto/'s wire adapter through its own per-field checks with
// error codes, offline tools on the frames they load); CollaborativeSystem::submit asserts it;
// ClientSlam::process takes it as given.
#include <cmath>
#include <string>

#include "frame/rgbd_frame.h"

namespace cslam {

// Empty if `f` fits `camera`; else why not, in words for a log line or an error reply.
inline std::string frame_problem(const RgbdFrame& f, const PinholeCamera& camera) {
  // Called on every frame: nothing is allocated unless the frame is refused.
  auto size = [&] { return std::to_string(camera.width) + "x" + std::to_string(camera.height); };
  if (f.bgr.empty() || f.bgr.type() != CV_8UC3 || f.bgr.cols != camera.width || f.bgr.rows != camera.height)
    return "colour image is not " + size() + " BGR8";
  // No depth image: a colour-only frame (tracked, never a keyframe). Subsampled depth
  // (depth_subsample > 1) comes spread to full size: tracked, never a keyframe.
  if (!f.depth.empty() && (f.depth.type() != CV_16UC1 || f.depth.cols != camera.width || f.depth.rows != camera.height))
    return "depth image is not " + size() + " 16-bit";
  if (f.depth_subsample < 1) return "depth subsample " + std::to_string(f.depth_subsample) + " is below 1";
  if (!std::isfinite(f.timestamp)) return "timestamp is not finite";
  if (!std::isfinite(f.depth_time_offset) || std::abs(f.depth_time_offset) > kMaxDepthTimeOffset)
    return "depth image " + std::to_string(f.depth_time_offset) + " s from the colour image (at most " +
           std::to_string(kMaxDepthTimeOffset) + " s)";
  return {};
}

}  // namespace cslam
