#pragma once
// JSON form of a client's pose latency on the server (stats.json of cslam-server and cslam-slam,
// /api/clients/K): last, p50 and p99 of receipt to pose, and each part's p99 (where the time goes).
#include <nlohmann/json.hpp>

#include "system/collaborative_system.h"

namespace cslam {

inline nlohmann::json pose_latency_json(const ClientSnapshot& c) {
  const auto& p = c.pose_latency_parts_p99;
  return {{"last", c.pose_latency_last_ms},
          {"p50", c.pose_latency_p50_ms},
          {"p99", c.pose_latency_p99_ms},
          {"samples", c.pose_latency_samples},
          {"parts_p99",
           {{"decode", p.decode_ms},
            {"queue", p.queue_ms},
            {"slot", p.slot_ms},
            {"mapping_wait", p.mapping_wait_ms},
            {"work", p.work_ms},
            {"work_cpu", p.work_cpu_ms}}}};
}

}  // namespace cslam
