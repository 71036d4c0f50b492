#include "client/pose_log.h"

#include <algorithm>
#include <fstream>

#include "core/error.h"
#include "io/trajectory_io.h"

namespace cslam::client {

namespace {

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(p * double(v.size() - 1) + 0.5))];
}

}  // namespace

void PoseLog::write(const std::string& path) const {
  Trajectory tracked;
  for (const auto& f : feedback_)
    if (f.has_pose) tracked.push_back({f.timestamp, f.T_world_cam});
  write_tum_trajectory(path, tracked, "poses received in acks (camera-to-world, group frame named in the ack)");
  std::ofstream csv(path + ".feedback.csv");
  if (!csv) throw ConfigError("cannot write " + path + ".feedback.csv");
  csv << "seq,timestamp,state,group,map,map_epoch,frames_skipped,latency_ms,server_ms\n";
  csv.precision(6);
  for (const auto& f : feedback_)
    csv << f.seq << "," << std::fixed << f.timestamp << "," << to_string(f.fate) << "," << f.group << "," << f.map
        << "," << f.map_epoch << "," << f.frames_skipped << "," << f.latency_ms << "," << f.server_ms << "\n";
}

nlohmann::json PoseLog::summary(const SenderStats& stats, double wall_s, std::size_t dataset_frames) const {
  std::map<std::string, std::uint64_t> states;
  std::vector<double> latency, server;
  for (const auto& f : feedback_) {
    ++states[to_string(f.fate)];
    if (f.fate == FrameFate::kSkipped) continue;
    latency.push_back(f.latency_ms);
    server.push_back(f.server_ms);
  }
  std::uint64_t errors = 0;
  for (const auto& [code, n] : stats.errors) errors += n;
  const std::uint64_t processed = feedback_.size() - (states.count("skipped") ? states.at("skipped") : 0);
  return {{"dataset_frames", dataset_frames},
          {"frames_offered", stats.frames_offered},
          {"frames_sent", stats.frames_sent},
          {"frames_dropped_client", stats.frames_dropped_live},
          {"acks", stats.acks},
          {"frames_processed", processed},
          {"states", states},
          {"errors", errors},
          {"bytes_sent", stats.bytes_sent},
          {"bytes_per_s", wall_s > 0 ? double(stats.bytes_sent) / wall_s : 0.0},
          {"frames_light", stats.frames_light},
          {"bytes_light", stats.bytes_light},
          {"depth_requests", stats.depth_requests},
          {"depth_request_lag_frames",
           {{"mean", stats.depth_requests_met ? double(stats.depth_request_lag_sum) / stats.depth_requests_met : 0.0},
            {"max", stats.depth_request_lag_max}}},
          {"colour_key_packets", stats.colour_key_packets},
          {"stream_gaps", stats.stream_gaps},
          {"rate_steps_down", stats.rate_steps_down},
          {"rate_steps_up", stats.rate_steps_up},
          {"depth_every_last", stats.depth_every},
          {"frames_finer", stats.frames_finer},
          {"wall_s", wall_s},
          {"processed_fps", wall_s > 0 ? double(processed) / wall_s : 0.0},
          {"latency_ms",
           {{"p50", percentile(latency, 0.5)},
            {"p99", percentile(latency, 0.99)},
            {"max", latency.empty() ? 0.0 : *std::max_element(latency.begin(), latency.end())}}},
          {"server_ms", {{"p50", percentile(server, 0.5)}, {"p99", percentile(server, 0.99)}}}};
}

}  // namespace cslam::client
