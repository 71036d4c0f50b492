#include "server/http/status_cache.h"

#include "server/http/auth_gate.h"
#include "server/http/http_guard.h"

#include "core/ids_json.h"
#include "core/log.h"
#include "core/thread_priority.h"

#include <sstream>

namespace cslam::http {
namespace {

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

nlohmann::json pose_json(const SE3& T_world_cam, double timestamp) {
  const auto& t = T_world_cam.translation();
  const auto& q = T_world_cam.rotation();
  return {{"timestamp", timestamp}, {"position", {t.x(), t.y(), t.z()}}, {"quaternion", {q.x(), q.y(), q.z(), q.w()}}};
}

}  // namespace

StatusCache::StatusCache(const CollaborativeSystem& system, CacheConfig config)
    : system_(system), config_(std::move(config)), state_(std::make_shared<CachedState>()) {}

StatusCache::~StatusCache() { stop(); }

void StatusCache::start() {
  refresh();
  if (!thread_.joinable()) thread_ = std::thread([this] { loop(); });
}

void StatusCache::stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

std::shared_ptr<const CachedState> StatusCache::get() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return state_;
}

void StatusCache::loop() {
  name_current_thread("http-status");
  const auto period = std::chrono::duration<double>(1.0 / std::max(0.1, config_.refresh_hz));
  std::unique_lock<std::mutex> lock(mutex_);
  while (!wake_.wait_for(lock, period, [this] { return stop_; })) {
    lock.unlock();
    refresh();
    lock.lock();
  }
}

void StatusCache::add_snapshots(CachedState& next) {
  if (!map_store_) return;
  try {
    const nlohmann::json j = nlohmann::json::parse(map_store_->stats_json());
    next.snapshots_on = !j.value("state_dir", std::string()).empty();
    if (!next.snapshots_on) return;
    next.snapshot_failing_for_s = j.value("failing_for_s", 0.0);
    next.snapshot_last_error = j.value("last_error", std::string());
    next.status["snapshots"] = {{"written", j.value("written", std::uint64_t(0))},
                                {"failed", j.value("failed", std::uint64_t(0))},
                                {"last_success_age_s", j.value("last_success_age_s", nlohmann::json())},
                                {"failing_for_s", next.snapshot_failing_for_s},
                                {"last_error", next.snapshot_last_error}};
    next.metrics += snapshot_metrics_text(j);
  } catch (const std::exception& e) {
    logger("http")->error("status: snapshot counters unreadable: {}", e.what());
  }
}

void StatusCache::add_recon(CachedState& next) {
  if (!recon_) return;
  recon_->expire();  // finished jobs past their age go even when nobody asks
  const ReconStats r = recon_->stats();
  next.status["reconstruction"] = recon_json(r);
  next.metrics += recon_metrics_text(r);
}

void StatusCache::apply_extra(CachedState& next) {
  if (!extra_) return;
  // The contribution works on copies: a throw half-way leaves the published status untouched.
  nlohmann::json status = next.status;
  std::string metrics = next.metrics;
  std::string error;
  try {
    extra_(status, metrics);
    // A hook may put bytes that are not UTF-8 into the status: fail here, not in every reply.
    (void)status.dump();
  } catch (const std::exception& e) {
    error = e.what();
  } catch (...) {
    error = "unknown exception";
  }
  if (error.empty()) {
    next.status = std::move(status);
    next.metrics = std::move(metrics);
  } else {
    ++extra_errors_;
    if (error != last_extra_error_) logger("http")->error("status: a status/metrics contribution failed: {}", error);
    last_extra_error_ = error;
  }
  next.status["status_extra_errors"] = extra_errors_;
  next.metrics +=
      "# HELP cslam_status_extra_errors_total Refreshes whose status/metrics contribution threw.\n"
      "# TYPE cslam_status_extra_errors_total counter\n"
      "cslam_status_extra_errors_total " +
      std::to_string(extra_errors_) + "\n";
}

namespace {

const NetClientStatus* link_of(const NetStatus* net, ClientId id) {
  if (!net) return nullptr;
  const auto it = net->clients.find(id);
  return it == net->clients.end() ? nullptr : &it->second;
}

// Frames processed and frames received per second over the samples' window.
std::pair<double, double> frame_rates(const std::deque<RateSample>& samples) {
  if (samples.size() < 2 || samples.back().t <= samples.front().t) return {0.0, 0.0};
  const double dt = samples.back().t - samples.front().t;
  return {double(samples.back().processed - samples.front().processed) / dt,
          double(samples.back().submitted - samples.front().submitted) / dt};
}

}  // namespace

std::string StatusCache::connection_of(const ClientSnapshot& c, const NetStatus* net, double now,
                                       const std::deque<RateSample>& samples) {
  if (samples.size() < 2 || samples[samples.size() - 2].submitted != c.frames_submitted ||
      !last_input_change_.count(c.id))
    last_input_change_[c.id] = now;
  const bool busy = c.queue_depth > 0 || now - last_input_change_[c.id] < config_.idle_after_s;
  std::string connection = c.frames_submitted == 0 ? "connected" : busy ? "streaming" : "idle";
  if (!net) return connection;
  // The network layer knows better: a vanished peer is "disconnected", not "idle".
  const auto it = net->clients.find(c.id);
  if (it == net->clients.end()) {
    // Not a live session in this status: reclaimed, or registered after it was published.
    if (net->reclaimed.count(c.id)) connection = "reclaimed";
  } else if (it->second.connection != "active") {
    connection = it->second.connection;
  }
  return connection;
}

nlohmann::json StatusCache::client_entry(const ClientSnapshot& c, const NetStatus* net, double now, double* fps) {
  auto& samples = samples_[c.id];
  const NetClientStatus* link = link_of(net, c.id);
  samples.push_back({now, c.frames_submitted, c.frames_processed, link ? net_counter(*link, "bytes_received") : 0});
  while (samples.size() > 2 && now - samples.front().t > 2.0) samples.pop_front();
  const auto [processed_fps, input_fps] = frame_rates(samples);
  *fps = processed_fps;
  nlohmann::json j = client_json(c, processed_fps, input_fps, connection_of(c, net, now, samples));
  if (link) j["link"] = link_json(*link, samples);
  j["pose"] = pose_json(c.T_world_cam, c.last_timestamp);  // the viewer places each robot's camera with it
  return j;
}

nlohmann::json StatusCache::add_clients(CachedState& next, const SystemSnapshot& snap, const NetStatus* net, double now,
                                        std::map<ClientId, double>& fps_of) {
  nlohmann::json clients = nlohmann::json::array();
  for (const ClientSnapshot& c : snap.clients) {
    nlohmann::json j = client_entry(c, net, now, &fps_of[c.id]);
    clients.push_back(j);
    next.clients[c.id] = std::move(j);
    next.group_of[c.id] = c.group;
  }
  return clients;
}

void StatusCache::compose(CachedState& next, const SystemSnapshot& snap, const NetStatus* net, nlohmann::json clients,
                          const std::map<ClientId, double>& fps_of) {
  std::size_t fusions = 0;
  nlohmann::json events = nlohmann::json::array();
  for (const FusionEvent& e : snap.events) {
    events.push_back(event_json(e));
    ++fusions;
  }
  next.status = {{"server", "cslam-server"},      {"version", config_.version},    {"uptime_s", snap.uptime_s},
                 {"generation", next.generation}, {"clients", std::move(clients)}, {"groups", next.groups},
                 {"fusion_events", fusions}};
  if (net) next.status["network"] = network_json(*net);
  next.events_body = nlohmann::json{{"events", std::move(events)}}.dump();
  next.metrics = metrics_text(snap, fps_of, fusions);
  if (net) next.metrics += network_metrics_text(*net);
  if (guard_) next.metrics += guard_metrics_text(*guard_);
  if (auth_) next.metrics += auth_->metrics_text();
}

void StatusCache::add_points(CachedState& next, double now) {
  const auto previous = get();
  if (now - last_points_t_ < config_.points_refresh_s) {
    next.points = previous->points;  // shared, immutable
    return;
  }
  last_points_t_ = now;
  for (const auto& [group, members] : next.groups)
    next.points[group] =
        std::make_shared<const std::vector<ViewerPoint>>(system_.map_points(group, config_.max_map_points));
}

void StatusCache::refresh() {
  auto next = std::make_shared<CachedState>();
  const SystemSnapshot snap = system_.snapshot();
  next->trajectories = system_.trajectories();
  next->groups = system_.groups();
  const double now = seconds_since(start_);
  next->uptime_s = snap.uptime_s;
  next->generation = ++generation_;
  const std::shared_ptr<const NetStatus> net = network_ ? network_->get() : nullptr;
  std::map<ClientId, double> fps_of;
  nlohmann::json clients = add_clients(*next, snap, net.get(), now, fps_of);
  compose(*next, snap, net.get(), std::move(clients), fps_of);
  add_snapshots(*next);
  add_recon(*next);
  apply_extra(*next);
  next->status_body = next->status.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  add_points(*next, now);
  std::lock_guard<std::mutex> lock(mutex_);
  state_ = std::move(next);
}

}  // namespace cslam::http
