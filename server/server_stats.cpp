#include "server/server_stats.h"
#include "server/heap.h"

#include <algorithm>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "core/stats.h"
#include "server/session_table.h"

namespace cslam::server {

std::uint64_t ClientNetStats::dropped_total() const {
  std::uint64_t n = 0;
  for (const auto& [reason, count] : dropped) n += count;
  return n;
}

void ServerStats::note_loop(double ms, double cpu_ms) {
  loop_max_ms_ = std::max(loop_max_ms_, ms);
  loop_max_cpu_ms_ = std::max(loop_max_cpu_ms_, cpu_ms);
  loops_over_20ms_ += ms > 20.0;
}

void ServerStats::note_message(const char* kind, double ms, double cpu_ms) {
  ++messages_;
  double& by_kind = message_max_ms_by_kind_[kind];
  by_kind = std::max(by_kind, ms);
  double& cpu_by_kind = message_max_cpu_ms_by_kind_[kind];
  cpu_by_kind = std::max(cpu_by_kind, cpu_ms);
  message_max_cpu_ms_ = std::max(message_max_cpu_ms_, cpu_ms);
  message_max_ms_ = std::max(message_max_ms_, ms);
  messages_over_20ms_ += ms > 20.0;
}

void ServerStats::note_decode(double ms) { decode_max_ms_ = std::max(decode_max_ms_, ms); }

namespace {

std::map<std::string, std::uint64_t> client_counters(const ClientNetStats& net) {
  return {{"frames_accepted", net.frames_accepted},
          {"bytes_received", net.bytes_received},
          {"messages", net.messages},
          {"heartbeats", net.heartbeats},
          {"reconnects", net.reconnects},
          {"timeouts", net.timeouts},
          {"goodbyes", net.goodbyes},
          {"dropped", net.dropped_total()},
          {"frames_light", net.frames_light},
          {"raw_bytes", net.raw_bytes}};
}

}  // namespace

http::NetStatus ServerStats::net_status(const SessionTable& sessions) const {
  http::NetStatus s;
  s.totals = {{"bytes_received", total_bytes_},
              {"frames_accepted", frames_total_},
              {"messages", messages_},
              {"sessions", sessions.size()},
              {"max_clients", sessions.max_clients()},
              {"sessions_reclaimed", reclaimed_},
              {"receive_loops_over_20ms", loops_over_20ms_},
              {"messages_over_20ms", messages_over_20ms_}};
  s.unattributed = unattributed_;
  s.transport = transport_;
  s.gauges = {{"receive_loop_max_ms", loop_max_ms_},
              {"message_max_ms", message_max_ms_},
              {"receive_loop_max_cpu_ms", loop_max_cpu_ms_},
              {"message_max_cpu_ms", message_max_cpu_ms_},
              {"decode_max_ms", decode_max_ms_}};
  for (const auto& [kind, ms] : message_max_ms_by_kind_) s.gauges[std::string(kind) + "_message_max_ms"] = ms;
  for (const auto& [id, session] : sessions.sessions()) {
    http::NetClientStatus c;
    c.id = id;
    c.connection = to_string(session.state);
    if (auto it = clients_.find(id); it != clients_.end()) {
      c.counters = client_counters(it->second);
      c.dropped = it->second.dropped;
    } else {
      c.counters = client_counters(ClientNetStats());
    }
    s.clients[id] = std::move(c);
  }
  return s;
}

std::vector<std::string> ServerStats::progress_lines(const SystemSnapshot& snapshot, double elapsed_s) {
  std::vector<std::string> lines;
  for (const ClientSnapshot& c : snapshot.clients) {
    const ClientNetStats& net = clients_[c.id];
    auto& [last_processed, last_bytes] = last_processed_bytes_[c.id];
    const double dt = elapsed_s > 0 ? elapsed_s : 1.0;
    const double fps = double(c.frames_processed - last_processed) / dt;
    const double mbps = double(net.bytes_received - last_bytes) / dt / 1e6;
    last_processed = c.frames_processed;
    last_bytes = net.bytes_received;
    char buf[320];
    std::snprintf(
        buf, sizeof buf,
        "client %u: received %llu processed %llu dropped %llu queue %zu | %.1f fps %.2f MB/s (1:%.0f, %llu light) | %s",
        unsigned(c.id), (unsigned long long)net.frames_accepted, (unsigned long long)c.frames_processed,
        (unsigned long long)net.dropped_total(), c.queue_depth, fps, mbps,
        net.bytes_received > 0 ? double(net.raw_bytes) / double(net.bytes_received) : 0.0,
        (unsigned long long)net.frames_light, tracking_label(c.tracking));
    lines.emplace_back(buf);
  }
  const HeapStats heap = heap_stats();
  char buf[160];
  std::snprintf(buf, sizeof buf, "process: resident %.0f MB", double(resident_bytes()) / 1e6);
  lines.emplace_back(buf);
  if (heap.known) {
    std::snprintf(buf, sizeof buf, " | heap %.0f MB held, %.0f MB free", double(heap.allocated) / 1e6,
                  double(heap.free_mapped) / 1e6);
    lines.back() += buf;
  }
  return lines;
}

std::vector<std::string> ServerStats::summary_lines(const SystemSnapshot& snapshot, double wall_s) const {
  std::vector<std::string> lines;
  const double dt = wall_s > 0 ? wall_s : 1.0;
  for (const ClientSnapshot& c : snapshot.clients) {
    auto it = clients_.find(c.id);
    const ClientNetStats net = it == clients_.end() ? ClientNetStats() : it->second;
    const Summary t = summarize(net.decode_dispatch_ms);
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "client %u: received %llu processed %llu dropped %llu | %.1f fps %.2f MB/s average over %.1f s | "
                  "decode+dispatch median %.2f ms | %llu reconnects %llu timeouts",
                  unsigned(c.id), (unsigned long long)net.frames_accepted, (unsigned long long)c.frames_processed,
                  (unsigned long long)net.dropped_total(), double(c.frames_processed) / dt,
                  double(net.bytes_received) / dt / 1e6, wall_s, t.median, (unsigned long long)net.reconnects,
                  (unsigned long long)net.timeouts);
    lines.emplace_back(buf);
  }
  return lines;
}

std::string ServerStats::to_json(const SystemSnapshot& snapshot, double wall_s) const {
  nlohmann::json j;
  j["wall_s"] = wall_s;
  j["bytes_received"] = total_bytes_;
  const double span_s = std::chrono::duration<double>(last_frame_ - first_frame_).count();
  j["frames_accepted"] = frames_total_;
  j["first_to_last_frame_s"] = span_s;
  j["throughput_fps"] = frames_total_ > 1 && span_s > 0 ? double(frames_total_ - 1) / span_s : 0.0;
  j["throughput_mb_s"] = span_s > 0 ? double(total_bytes_) / span_s / 1e6 : 0.0;
  j["unattributed"] = unattributed_;
  j["transport_events"] = transport_;
  j["messages"] = messages_;
  j["sessions_reclaimed"] = reclaimed_;
  j["receive_loop_max_ms"] = loop_max_ms_;
  j["receive_loops_over_20ms"] = loops_over_20ms_;
  j["message_max_ms"] = message_max_ms_;
  j["messages_over_20ms"] = messages_over_20ms_;
  j["message_max_ms_by_kind"] = message_max_ms_by_kind_;
  j["receive_loop_max_cpu_ms"] = loop_max_cpu_ms_;
  j["message_max_cpu_ms"] = message_max_cpu_ms_;
  j["message_max_cpu_ms_by_kind"] = message_max_cpu_ms_by_kind_;
  j["decode_max_ms"] = decode_max_ms_;
  std::vector<double> all_ms;
  j["clients"] = nlohmann::json::array();
  for (const auto& [id, net] : clients_) {
    nlohmann::json c;
    c["id"] = id;
    c["frames_accepted"] = net.frames_accepted;
    c["bytes_received"] = net.bytes_received;
    c["messages"] = net.messages;
    c["heartbeats"] = net.heartbeats;
    c["reconnects"] = net.reconnects;
    c["timeouts"] = net.timeouts;
    c["goodbyes"] = net.goodbyes;
    c["dropped"] = net.dropped;
    c["dropped_total"] = net.dropped_total();
    c["frames_light"] = net.frames_light;
    c["raw_bytes"] = net.raw_bytes;
    for (const ClientSnapshot& s : snapshot.clients)
      if (s.id == id) c["frames_processed"] = s.frames_processed;
    const Summary t = summarize(net.decode_dispatch_ms);
    c["decode_dispatch_ms"] = {{"n", t.n},     {"median", t.median}, {"mean", t.mean},
                               {"min", t.min}, {"max", t.max},       {"p95", t.p95}};
    all_ms.insert(all_ms.end(), net.decode_dispatch_ms.begin(), net.decode_dispatch_ms.end());
    j["clients"].push_back(c);
  }
  const Summary t = summarize(all_ms);
  j["decode_dispatch_ms"] = {{"n", t.n},     {"median", t.median}, {"mean", t.mean},
                             {"min", t.min}, {"max", t.max},       {"p95", t.p95}};
  return j.dump(2);
}

}  // namespace cslam::server
