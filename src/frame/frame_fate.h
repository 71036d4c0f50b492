#pragma once
// What tracking made of a frame: the one spelling from the tracker to the Ack. The tracker's state
// is the fate of its last frame (one of the first three); the worker adds kSkipped and kRejected;
// proto/ maps it to the wire enum in one place (pose_feedback.cpp).
namespace cslam {

enum class FrameFate { kNotInitialized, kTracked, kLost, kSkipped, kRejected };

inline const char* to_string(FrameFate f) {
  switch (f) {
    case FrameFate::kNotInitialized:
      return "not_initialized";
    case FrameFate::kTracked:
      return "tracked";
    case FrameFate::kLost:
      return "lost";
    case FrameFate::kSkipped:
      return "skipped";
    case FrameFate::kRejected:
      return "rejected";
  }
  return "unknown";
}

}  // namespace cslam
