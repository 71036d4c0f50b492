#pragma once
// JSON form of one client's loop-closing statistics (stats.json of cslam-slam and cslam-server):
// every accepted loop with its verified transform (checked by `cslam-eval events`), query and
// global-BA timings.
#include <cmath>

#include <nlohmann/json.hpp>

#include "eval/stats_json.h"
#include "io/trajectory_io.h"
#include "slam/loop/loop_closer.h"

namespace cslam {

inline nlohmann::json loop_events_json(const LoopClosingStats& s) {
  nlohmann::json loops = nlohmann::json::array();
  for (const auto& l : s.loops)
    loops.push_back({{"query_timestamp", l.query_timestamp},
                     {"candidate_timestamp", l.candidate_timestamp},
                     {"inliers", l.inliers},
                     {"correction_ms", l.correction_ms},
                     {"pose_graph_ms", l.pose_graph_ms},
                     {"correction_translation_m", l.T_correction.translation().norm()},
                     {"correction_rotation_deg", l.T_correction.rotation_angle() * 180.0 / M_PI},
                     {"T_query_candidate", format_tum_line({0.0, l.T_query_candidate})}});
  return loops;
}

// Adds loops, loop_query_ms, global_ba_* and loop_events to `out`.
inline void add_loop_stats(nlohmann::json& out, const LoopClosingStats& s) {
  out["loops"] = s.loops.size();
  out["loop_query_ms"] = summary_json(s.query_ms);
  out["global_ba_ms"] = summary_json(s.global_ba_ms);
  out["global_ba_completed"] = s.global_ba_completed;
  out["global_ba_discarded"] = s.global_ba_discarded;
  out["loop_events"] = loop_events_json(s);
}

}  // namespace cslam
