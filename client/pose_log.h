#pragma once
// What a client program keeps of the pose feedback it received: every ack's state, the tracked
// poses (written as a TUM trajectory) and the frame-to-pose latency, plus a JSON summary.
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "client/frame_sender.h"

namespace cslam::client {

class PoseLog {
 public:
  void add(const wire::PoseFeedback& f) { feedback_.push_back(f); }
  const std::vector<wire::PoseFeedback>& feedback() const { return feedback_; }

  // TUM trajectory of the tracked frames (camera-to-world, each in the group frame its ack
  // named), then PATH.feedback.csv with one line per ack: state, group, map, epoch, latency.
  void write(const std::string& path) const;
  // Counts per state and latency percentiles (tracked frames), with the sender's counters.
  nlohmann::json summary(const SenderStats& stats, double wall_s, std::size_t dataset_frames) const;

 private:
  std::vector<wire::PoseFeedback> feedback_;
};

}  // namespace cslam::client
