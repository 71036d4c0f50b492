#pragma once
// Configuration of the collaborative system as plain structs with defaults.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>

#include "core/ids.h"
#include "fusion/fusion_manager.h"
#include "slam/slam_config.h"

namespace cslam {

struct SystemConfig {
  // Frames queued per client before submit() blocks the producer.
  std::size_t client_queue_capacity = 8;
  // Vocabulary file for BoW (empty: the project's default vocabulary).
  std::string vocabulary_path;
  // Map fusion across clients (rate, thresholds).
  FusionConfig fusion;
  // Run the SLAM stages (false: only count frames and record timestamps, for network tests).
  bool run_slam = true;
  // Per-client SLAM settings (every client gets the same).
  SlamConfig slam;
  // Called from a client's worker thread after each frame has been consumed (processed or
  // rejected), e.g. so the network layer can hand the client a flow-control credit back.
  // Must be cheap and must not call back into the system.
  std::function<void(ClientId client, std::uint64_t seq)> on_frame_done;
};

}  // namespace cslam
