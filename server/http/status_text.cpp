// The serialisers of the status cache (status_cache.h): JSON parts of /api/status and the
// Prometheus text of /metrics.
#include <sstream>

#include "server/http/http_guard.h"
#include "server/http/status_cache.h"

#include "core/ids_json.h"
#include "system/pose_latency_json.h"

namespace cslam::http {
namespace {

// Prometheus label values: backslash, quote and newline escaped.
std::string label(const std::string& v) {
  std::string out;
  for (char c : v) {
    if (c == '\\' || c == '"') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out;
}

void head(std::ostringstream& o, const std::string& name, const char* type, const std::string& help) {
  o << "# HELP " << name << " " << help << "\n# TYPE " << name << " " << type << "\n";
}

// One line per client: name{client="ID",name="NAME"} value(c).
template <typename F>
void per_client(std::ostringstream& o, const SystemSnapshot& s, const char* name, const char* type, const char* help,
                F value) {
  head(o, name, type, help);
  for (const ClientSnapshot& c : s.clients)
    o << name << "{client=\"" << c.id << "\",name=\"" << label(c.name) << "\"} " << value(c) << "\n";
}

void frame_counters(std::ostringstream& o, const SystemSnapshot& s) {
  per_client(o, s, "cslam_frames_received_total", "counter", "Frames received (submitted to SLAM).",
             [](const ClientSnapshot& c) { return c.frames_submitted; });
  per_client(o, s, "cslam_frames_processed_total", "counter", "Frames processed by SLAM.",
             [](const ClientSnapshot& c) { return c.frames_processed; });
  per_client(o, s, "cslam_frames_dropped_total", "counter", "Frames rejected (bad images).",
             [](const ClientSnapshot& c) { return c.frames_rejected; });
  per_client(o, s, "cslam_frames_lost_total", "counter", "Frames processed while tracking was lost.",
             [](const ClientSnapshot& c) { return c.frames_lost; });
  per_client(o, s, "cslam_frames_skipped_total", "counter", "Live frames skipped because a newer one was queued.",
             [](const ClientSnapshot& c) { return c.frames_skipped; });
  per_client(o, s, "cslam_frames_flow_total", "counter",
             "Frames tracked as flow frames (optical flow, no ORB extraction).",
             [](const ClientSnapshot& c) { return c.frames_flow; });
}

void client_gauges(std::ostringstream& o, const SystemSnapshot& s, const std::map<ClientId, double>& fps) {
  per_client(o, s, "cslam_fps", "gauge", "Frames processed per second (last seconds).",
             [&fps](const ClientSnapshot& c) {
               const auto it = fps.find(c.id);
               return it == fps.end() ? 0.0 : it->second;
             });
  per_client(o, s, "cslam_queue_depth", "gauge", "Frames queued before the SLAM worker.",
             [](const ClientSnapshot& c) { return c.queue_depth; });
  per_client(o, s, "cslam_keyframes", "gauge", "Keyframes in the client's map.",
             [](const ClientSnapshot& c) { return c.keyframes; });
  per_client(o, s, "cslam_map_points", "gauge", "Map points in the client's map.",
             [](const ClientSnapshot& c) { return c.map_points; });
  per_client(o, s, "cslam_group", "gauge", "Fused group id of the client.",
             [](const ClientSnapshot& c) { return c.group.value(); });
}

void tracking_states(std::ostringstream& o, const SystemSnapshot& s) {
  head(o, "cslam_tracking_state", "gauge", "1 for the client's current tracking state.");
  for (const ClientSnapshot& c : s.clients)
    for (FrameFate st : {FrameFate::kNotInitialized, FrameFate::kTracked, FrameFate::kLost})
      o << "cslam_tracking_state{client=\"" << c.id << "\",state=\"" << tracking_label(st) << "\"} "
        << (c.tracking == st ? 1 : 0) << "\n";
}

bool gauge_total(const std::string& k) {
  return k == "sessions" || k == "max_clients" || k == "sessions_reclaiming" || k == "decode_queue" ||
         k == "process_threads";
}

void net_totals(std::ostringstream& o, const NetStatus& n) {
  for (const auto& [k, v] : n.totals) {
    const std::string name = gauge_total(k) ? "cslam_net_" + k : "cslam_net_" + k + "_total";
    head(o, name, gauge_total(k) ? "gauge" : "counter", "Network: " + k + " (network_stats.json).");
    o << name << " " << v << "\n";
  }
  for (const auto& [k, v] : n.gauges) {
    head(o, "cslam_net_" + k, "gauge", "Network: " + k + " since start.");
    o << "cslam_net_" << k << " " << v << "\n";
  }
}

void net_events(std::ostringstream& o, const NetStatus& n) {
  head(o, "cslam_net_unattributed_dropped_total", "counter",
       "Messages dropped from peers without a session, by reason.");
  for (const auto& [reason, v] : n.unattributed)
    o << "cslam_net_unattributed_dropped_total{reason=\"" << label(reason) << "\"} " << v << "\n";
  head(o, "cslam_net_transport_events_total", "counter",
       "Connection events (accepted, disconnected, auth_failed, ...).");
  for (const auto& [event, v] : n.transport)
    o << "cslam_net_transport_events_total{event=\"" << label(event) << "\"} " << v << "\n";
}

// Per client: at most --max-clients sessions, so the label set is bounded.
void net_clients(std::ostringstream& o, const NetStatus& n) {
  std::map<std::string, std::vector<std::pair<ClientId, std::uint64_t>>> per_counter;
  for (const auto& [id, c] : n.clients)
    for (const auto& [k, v] : c.counters) per_counter[k].emplace_back(id, v);
  for (const auto& [k, values] : per_counter) {
    const std::string name = "cslam_net_client_" + k + "_total";
    head(o, name, "counter", "Network, per client: " + k + ".");
    for (const auto& [id, v] : values) o << name << "{client=\"" << id << "\"} " << v << "\n";
  }
  head(o, "cslam_net_client_dropped_by_reason_total", "counter", "Frames/messages of a client dropped, by reason.");
  for (const auto& [id, c] : n.clients)
    for (const auto& [reason, v] : c.dropped)
      o << "cslam_net_client_dropped_by_reason_total{client=\"" << id << "\",reason=\"" << label(reason) << "\"} " << v
        << "\n";
  head(o, "cslam_net_client_connection", "gauge", "1 for the client's connection state.");
  for (const auto& [id, c] : n.clients)
    for (const char* st : {"active", "disconnected", "done"})
      o << "cslam_net_client_connection{client=\"" << id << "\",state=\"" << st << "\"} "
        << (c.connection == st ? 1 : 0) << "\n";
}

}  // namespace

std::uint64_t net_counter(const NetClientStatus& net, const char* key) {
  const auto it = net.counters.find(key);
  return it == net.counters.end() ? 0 : it->second;
}

nlohmann::json client_json(const ClientSnapshot& c, double fps, double input_fps, const std::string& connection) {
  return {{"id", c.id},
          {"name", c.name},
          {"connection", connection},
          {"tracking", tracking_label(c.tracking)},
          {"frames_received", c.frames_submitted},
          {"frames_processed", c.frames_processed},
          {"frames_dropped", c.frames_rejected},
          {"frames_lost", c.frames_lost},
          {"frames_skipped", c.frames_skipped},
          {"frames_flow", c.frames_flow},
          {"pose_latency_ms", pose_latency_json(c)},
          {"queue_depth", c.queue_depth},
          {"fps", fps},
          {"input_fps", input_fps},
          {"link", nullptr},  // set from the receiver's counters when the server has a network layer
          {"keyframes", c.keyframes},
          {"map_points", c.map_points},
          {"maps", c.maps},
          {"group", c.group},
          {"last_timestamp", c.last_timestamp}};
}

nlohmann::json link_json(const NetClientStatus& net, const std::deque<RateSample>& samples) {
  const std::uint64_t bytes = net_counter(net, "bytes_received"), raw = net_counter(net, "raw_bytes");
  nlohmann::json j = {{"bytes_per_s", nullptr},
                      {"bytes_received", bytes},
                      {"raw_bytes", raw},
                      {"compression_ratio", bytes > 0 ? double(raw) / double(bytes) : 0.0},
                      {"frames_light", net_counter(net, "frames_light")}};
  if (samples.size() >= 2 && samples.back().t > samples.front().t && samples.back().bytes >= samples.front().bytes)
    j["bytes_per_s"] = double(samples.back().bytes - samples.front().bytes) / (samples.back().t - samples.front().t);
  return j;
}

nlohmann::json event_json(const FusionEvent& e) {
  return {{"time_s", e.wall_time_s},
          {"kind", e.kind},
          {"clients", {e.client_a, e.client_b}},
          {"group", e.group},
          {"inliers", e.inliers},
          {"duration_ms", e.duration_ms},
          {"query_timestamp", e.query_timestamp},
          {"candidate_timestamp", e.candidate_timestamp},
          {"seam_points", e.seam_points},
          {"seam_edges", e.seam_edges}};
}

std::string metrics_text(const SystemSnapshot& s, const std::map<ClientId, double>& fps, std::size_t fusion_count) {
  std::ostringstream o;
  head(o, "cslam_uptime_seconds", "gauge", "Seconds since the system started.");
  o << "cslam_uptime_seconds " << s.uptime_s << "\n";
  head(o, "cslam_clients", "gauge", "Registered clients.");
  o << "cslam_clients " << s.clients.size() << "\n";
  frame_counters(o, s);
  client_gauges(o, s, fps);
  tracking_states(o, s);
  head(o, "cslam_fusion_events_total", "counter", "Accepted fusion and loop events.");
  o << "cslam_fusion_events_total " << fusion_count << "\n";
  return o.str();
}

nlohmann::json network_json(const NetStatus& n) {
  nlohmann::json j = {{"totals", n.totals},
                      {"unattributed", n.unattributed},
                      {"transport_events", n.transport},
                      {"timings_ms", n.gauges}};
  j["clients"] = nlohmann::json::array();
  for (const auto& [id, c] : n.clients) {
    nlohmann::json cj = {{"id", id}, {"connection", c.connection}, {"dropped", c.dropped}};
    for (const auto& [k, v] : c.counters) cj[k] = v;
    j["clients"].push_back(std::move(cj));
  }
  return j;
}

std::string network_metrics_text(const NetStatus& n) {
  std::ostringstream o;
  net_totals(o, n);
  net_events(o, n);
  net_clients(o, n);
  return o.str();
}

std::string guard_metrics_text(const GuardStats& g) {
  std::ostringstream o;
  o << "# HELP cslam_http_connections_accepted_total Connections accepted by the HTTP guard.\n"
       "# TYPE cslam_http_connections_accepted_total counter\n"
    << "cslam_http_connections_accepted_total " << g.accepted << "\n"
    << "# HELP cslam_http_requests_total Complete requests handed to the workers.\n"
       "# TYPE cslam_http_requests_total counter\n"
    << "cslam_http_requests_total " << g.requests << "\n"
    << "# HELP cslam_http_refused_total Requests or connections refused by the HTTP guard, by reason.\n"
       "# TYPE cslam_http_refused_total counter\n";
  const std::pair<const char*, std::uint64_t> reasons[] = {{"timed_out", g.timed_out},
                                                           {"header_too_large", g.header_too_large},
                                                           {"body_too_large", g.body_too_large},
                                                           {"bad_request", g.bad_request},
                                                           {"overloaded", g.overloaded},
                                                           {"connections", g.connections_refused},
                                                           {"tls_handshake", g.tls_handshake_failed},
                                                           {"plain_http_on_tls", g.plain_http_on_tls}};
  for (const auto& [reason, n] : reasons) o << "cslam_http_refused_total{reason=\"" << reason << "\"} " << n << "\n";
  return o.str();
}

std::string snapshot_metrics_text(const nlohmann::json& j) {
  std::ostringstream o;
  o << "# HELP cslam_snapshot_writes_total Map snapshot writes, by result.\n"
       "# TYPE cslam_snapshot_writes_total counter\n"
    << "cslam_snapshot_writes_total{result=\"ok\"} " << j.value("written", std::uint64_t(0)) << "\n"
    << "cslam_snapshot_writes_total{result=\"failed\"} " << j.value("failed", std::uint64_t(0)) << "\n"
    << "# HELP cslam_snapshot_failing_seconds Seconds since the first failed write after the last good one (0: the "
       "newest write succeeded).\n"
       "# TYPE cslam_snapshot_failing_seconds gauge\n"
    << "cslam_snapshot_failing_seconds " << j.value("failing_for_s", 0.0) << "\n";
  const auto age = j.find("last_success_age_s");
  if (age != j.end() && age->is_number())
    o << "# HELP cslam_snapshot_last_success_age_seconds Seconds since the last good snapshot was written.\n"
         "# TYPE cslam_snapshot_last_success_age_seconds gauge\n"
      << "cslam_snapshot_last_success_age_seconds " << age->get<double>() << "\n";
  return o.str();
}

nlohmann::json recon_json(const ReconStats& r) {
  return {{"jobs", r.jobs},
          {"running", r.running},
          {"bytes_held", r.bytes_held},
          {"started", r.started},
          {"expired", r.expired},
          {"refused_busy", r.refused_busy},
          {"refused_over_budget", r.refused_over_budget},
          {"stopped_over_budget", r.stopped_over_budget},
          {"max_mb", r.max_mb}};
}

std::string recon_metrics_text(const ReconStats& r) {
  std::ostringstream o;
  o << "# HELP cslam_recon_jobs Reconstruction jobs kept (running or finished, not yet expired).\n"
       "# TYPE cslam_recon_jobs gauge\ncslam_recon_jobs "
    << r.jobs << "\n"
    << "# HELP cslam_recon_bytes_held PLY bytes of finished reconstruction jobs kept for download.\n"
       "# TYPE cslam_recon_bytes_held gauge\ncslam_recon_bytes_held "
    << r.bytes_held << "\n"
    << "# HELP cslam_recon_jobs_total Reconstruction requests, by outcome.\n"
       "# TYPE cslam_recon_jobs_total counter\n"
    << "cslam_recon_jobs_total{outcome=\"started\"} " << r.started << "\n"
    << "cslam_recon_jobs_total{outcome=\"refused_busy\"} " << r.refused_busy << "\n"
    << "cslam_recon_jobs_total{outcome=\"refused_over_budget\"} " << r.refused_over_budget << "\n"
    << "cslam_recon_jobs_total{outcome=\"stopped_over_budget\"} " << r.stopped_over_budget << "\n"
    << "cslam_recon_jobs_total{outcome=\"expired\"} " << r.expired << "\n";
  return o.str();
}

}  // namespace cslam::http
