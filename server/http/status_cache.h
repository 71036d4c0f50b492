#pragma once
// The HTTP layer's view of the system: a thread refreshes an immutable snapshot (status JSON,
// events, metrics text, trajectories, groups, decimated map points) a few times per second from
// CollaborativeSystem's snapshot calls. HTTP handlers only read the latest published snapshot
// (a shared_ptr swap), so a slow or hostile HTTP client never holds a SLAM lock.
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "server/http/map_routes.h"
#include "server/http/net_status.h"
#include "server/http/recon_jobs.h"
#include "system/collaborative_system.h"

namespace cslam::http {

struct GuardStats;  // server/http/http_guard.h
class AuthGate;     // server/http/auth_gate.h

struct CacheConfig {
  double refresh_hz = 5.0;             // status, events, metrics, trajectories
  double points_refresh_s = 1.0;       // map points (the heaviest query) at most this often
  std::size_t max_map_points = 20000;  // per group
  double idle_after_s = 3.0;           // no new frame for this long: connection "idle"
  std::string version = "0.1.0";
};

struct CachedState {
  double uptime_s = 0;
  std::uint64_t generation = 0;
  nlohmann::json status;                        // GET /api/status
  std::string status_body;                      // ... serialised once per refresh
  std::map<ClientId, nlohmann::json> clients;   // body of GET /api/clients/{id} (with pose)
  std::string events_body;                      // body of GET /api/fusion/events
  std::string metrics;                          // body of GET /metrics
  std::map<ClientId, Trajectory> trajectories;  // each in its group's frame
  std::map<ClientId, GroupId> group_of;
  std::map<GroupId, std::vector<ClientId>> groups;
  std::map<GroupId, std::shared_ptr<const std::vector<ViewerPoint>>> points;  // per group, decimated
  // Snapshot writes (from MapStore::stats_json; absent without a store or without --state-dir).
  bool snapshots_on = false;
  double snapshot_failing_for_s = 0;  // 0 while the newest write succeeded
  std::string snapshot_last_error;
};

// Builds the status JSON/metrics from one system snapshot (pure; unit-tested).
struct RateSample {
  double t = 0;
  std::uint64_t submitted = 0, processed = 0;
  std::uint64_t bytes = 0;  // bytes received from the client (network counters; 0 without them)
};
// A client's link as the receiver counts it: {bytes_per_s over the rate window, bytes_received,
// raw_bytes (what the frames would take uncompressed: 3 B colour + 2 B depth per pixel),
// compression_ratio = raw_bytes / bytes_received, frames_light}. bytes_per_s is null until two
// samples span some time.
nlohmann::json link_json(const NetClientStatus& net, const std::deque<RateSample>& samples);
nlohmann::json client_json(const ClientSnapshot& c, double fps, double input_fps, const std::string& connection);
nlohmann::json event_json(const FusionEvent& e);
std::string metrics_text(const SystemSnapshot& s, const std::map<ClientId, double>& fps, std::size_t fusion_count);
// The network counters: JSON for /api/status "network", Prometheus text (cslam_net_*) for /metrics.
nlohmann::json network_json(const NetStatus& n);
std::string network_metrics_text(const NetStatus& n);
// A client's network counter by name (0 if absent).
std::uint64_t net_counter(const NetClientStatus& net, const char* key);
// The HTTP guard's counters (cslam_http_*) for /metrics.
std::string guard_metrics_text(const GuardStats& g);
// Snapshot writes (cslam_snapshot_*) from a MapStore's stats JSON, and reconstruction jobs (cslam_recon_*).
std::string snapshot_metrics_text(const nlohmann::json& stats);
nlohmann::json recon_json(const ReconStats& r);
std::string recon_metrics_text(const ReconStats& r);

class StatusCache {
 public:
  StatusCache(const CollaborativeSystem& system, CacheConfig config);
  ~StatusCache();  // stops and joins the refresh thread
  StatusCache(const StatusCache&) = delete;
  StatusCache& operator=(const StatusCache&) = delete;

  // Live network counters to merge into status and metrics (set before start(); may be null).
  void set_network(const NetStatusBoard* board) { network_ = board; }
  // The HTTP guard's counters (refusals by reason) for /metrics (set before start(); may be null).
  void set_guard_stats(const GuardStats* stats) { guard_ = stats; }
  // The bearer-token check's counters (cslam_http_auth_*) for /metrics (set before start(); may be null).
  void set_auth_gate(const AuthGate* gate) { auth_ = gate; }
  // Another component's contribution to /api/status and /metrics, called on every refresh (from
  // the refresh thread, no SLAM lock held): it may add keys to `status` (e.g. status["dense"]) and
  // append Prometheus lines to `metrics`. An exception from it is caught, logged (once per
  // message change) and counted in cslam_status_extra_errors_total; the refresh goes on without
  // its part. Set before start().
  // Snapshot writes for status, metrics and /api/health (set before start(); may be null).
  void set_map_store(const MapStore* store) { map_store_ = store; }
  // Reconstruction jobs: their counters in status and metrics; finished jobs past their age are
  // expired on each refresh (set before start(); may be null).
  void set_recon_jobs(ReconJobs* jobs) { recon_ = jobs; }
  using StatusExtra = std::function<void(nlohmann::json& status, std::string& metrics)>;
  void set_extra(StatusExtra extra) { extra_ = std::move(extra); }
  void start();    // starts the refresh thread (refresh() once first)
  void stop();     // idempotent
  void refresh();  // one refresh step (also usable without the thread, in tests)
  std::shared_ptr<const CachedState> get() const;

 private:
  void loop();

  const CollaborativeSystem& system_;
  const CacheConfig config_;
  const NetStatusBoard* network_ = nullptr;
  const GuardStats* guard_ = nullptr;
  const AuthGate* auth_ = nullptr;
  StatusExtra extra_;
  const MapStore* map_store_ = nullptr;
  ReconJobs* recon_ = nullptr;
  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  mutable std::mutex mutex_;  // guards state_ (pointer swap only) and stop_
  std::condition_variable wake_;
  bool stop_ = false;
  std::shared_ptr<const CachedState> state_;
  std::thread thread_;
  // Refresh-thread-only bookkeeping.
  std::map<ClientId, std::deque<RateSample>> samples_;
  std::map<ClientId, double> last_input_change_;
  double last_points_t_ = -1e9;
  std::uint64_t generation_ = 0;
  std::uint64_t extra_errors_ = 0;
  std::string last_extra_error_;
  // One refresh, step by step (refresh-thread only).
  nlohmann::json add_clients(CachedState& next, const SystemSnapshot& snap, const NetStatus* net, double now,
                             std::map<ClientId, double>& fps_of);  // the status's client list
  nlohmann::json client_entry(const ClientSnapshot& c, const NetStatus* net, double now, double* fps);
  std::string connection_of(const ClientSnapshot& c, const NetStatus* net, double now,
                            const std::deque<RateSample>& samples);
  void compose(CachedState& next, const SystemSnapshot& snap, const NetStatus* net, nlohmann::json clients,
               const std::map<ClientId, double>& fps_of);  // status, events, metrics
  void apply_extra(CachedState& next);
  void add_snapshots(CachedState& next);
  void add_recon(CachedState& next);
  void add_points(CachedState& next, double now);  // refreshed every points_refresh_s, else shared
};

}  // namespace cslam::http
