#include "system/collaborative_system.h"

#include <chrono>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <thread>

#include <nlohmann/json.hpp>

#include "core/bounded_queue.h"
#include "core/log.h"

namespace cslam {

const char* to_string(TrackingState s) {
  switch (s) {
    case TrackingState::kNotInitialized: return "not_initialized";
    case TrackingState::kTracking: return "tracking";
    case TrackingState::kLost: return "lost";
  }
  return "unknown";
}

// One client's worker: a bounded queue and the thread that drains it.
// (Until the SLAM core is wired in, the worker records each frame's timestamp with the
// identity pose; the interface stays the same.)
class ClientPipeline {
 public:
  ClientPipeline(const ClientInfo& info, const SystemConfig& config)
      : info_(info), config_(config), queue_(config.client_queue_capacity) {
    thread_ = std::thread([this] { run(); });
  }
  ~ClientPipeline() { finish(); }

  bool submit(RgbdFrame frame) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++snapshot_.frames_submitted;
    }
    return queue_.push(std::move(frame));
  }

  void finish() {
    queue_.close();
    if (thread_.joinable()) thread_.join();
  }

  ClientSnapshot snapshot() const {
    std::lock_guard<std::mutex> lock(mutex_);
    ClientSnapshot s = snapshot_;
    s.id = info_.id;
    s.name = info_.name;
    s.queue_depth = queue_.size();
    return s;
  }
  Trajectory trajectory() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return trajectory_;
  }
  const ClientInfo& info() const { return info_; }

 private:
  void run() {
    while (auto frame = queue_.pop()) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        trajectory_.push_back({frame->timestamp, SE3()});
        ++snapshot_.frames_processed;
        snapshot_.tracking = TrackingState::kTracking;
        snapshot_.last_timestamp = frame->timestamp;
        snapshot_.group = info_.id;
      }
      if (config_.on_frame_done) config_.on_frame_done(frame->client, frame->seq);
    }
  }

  const ClientInfo info_;
  const SystemConfig& config_;
  BoundedQueue<RgbdFrame> queue_;
  mutable std::mutex mutex_;
  ClientSnapshot snapshot_;
  Trajectory trajectory_;
  std::thread thread_;
};

struct CollaborativeSystem::Impl {
  SystemConfig config;
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  mutable std::mutex mutex;  // guards the client table (not the clients' contents)
  std::map<ClientId, std::unique_ptr<ClientPipeline>> clients;
  std::vector<FusionEvent> events;
  bool finished = false;
};

CollaborativeSystem::CollaborativeSystem(SystemConfig config) : impl_(std::make_unique<Impl>()) {
  impl_->config = std::move(config);
}

CollaborativeSystem::~CollaborativeSystem() { finish(); }

static bool same_camera(const PinholeCamera& a, const PinholeCamera& b) {
  return a.width == b.width && a.height == b.height && a.fx == b.fx && a.fy == b.fy && a.cx == b.cx && a.cy == b.cy &&
         a.dist == b.dist && a.depth_factor == b.depth_factor;
}

void CollaborativeSystem::add_client(const ClientInfo& info) {
  info.camera.validate();
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (impl_->finished) throw std::logic_error("add_client after finish()");
  auto it = impl_->clients.find(info.id);
  if (it != impl_->clients.end()) {
    if (!same_camera(it->second->info().camera, info.camera))
      throw std::invalid_argument("client " + std::to_string(info.id) + " re-registered with a different camera");
    return;
  }
  impl_->clients.emplace(info.id, std::make_unique<ClientPipeline>(info, impl_->config));
  logger("system")->info("client {} ('{}') registered, camera {} {}x{}", info.id, info.name, info.camera.name,
                         info.camera.width, info.camera.height);
}

bool CollaborativeSystem::has_client(ClientId id) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->clients.count(id) > 0;
}

bool CollaborativeSystem::submit(RgbdFrame frame) {
  ClientPipeline* pipeline = nullptr;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    if (impl_->finished) return false;
    auto it = impl_->clients.find(frame.client);
    if (it == impl_->clients.end()) return false;
    pipeline = it->second.get();
  }
  const PinholeCamera& cam = pipeline->info().camera;
  if (frame.bgr.type() != CV_8UC3 || frame.depth.type() != CV_16UC1 || frame.bgr.cols != cam.width ||
      frame.bgr.rows != cam.height || frame.depth.cols != cam.width || frame.depth.rows != cam.height) {
    throw std::invalid_argument("frame of client " + std::to_string(frame.client) + " does not match its camera (" +
                                std::to_string(cam.width) + "x" + std::to_string(cam.height) + ", BGR8 + depth16)");
  }
  // Pipelines are only destroyed in the destructor, after finish(): the pointer stays valid.
  return pipeline->submit(std::move(frame));
}

SystemSnapshot CollaborativeSystem::snapshot() const {
  SystemSnapshot s;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  s.uptime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - impl_->start).count();
  for (const auto& [id, p] : impl_->clients) s.clients.push_back(p->snapshot());
  s.events = impl_->events;
  return s;
}

void CollaborativeSystem::finish() {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (impl_->finished) return;
  impl_->finished = true;
  for (auto& [id, p] : impl_->clients) p->finish();
}

std::map<ClientId, Trajectory> CollaborativeSystem::trajectories() const {
  std::map<ClientId, Trajectory> out;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  for (const auto& [id, p] : impl_->clients) out[id] = p->trajectory();
  return out;
}

void CollaborativeSystem::write_outputs(const std::string& dir) const {
  std::filesystem::create_directories(dir);
  const auto trajs = trajectories();
  const auto snap = snapshot();
  nlohmann::json stats;
  stats["uptime_s"] = snap.uptime_s;
  for (const auto& c : snap.clients) {
    write_tum_trajectory(dir + "/client_" + std::to_string(c.id) + ".txt", trajs.at(c.id), "client " + std::to_string(c.id));
    stats["clients"].push_back({{"id", c.id}, {"name", c.name}, {"frames_submitted", c.frames_submitted},
                                {"frames_processed", c.frames_processed}, {"frames_rejected", c.frames_rejected},
                                {"keyframes", c.keyframes}, {"map_points", c.map_points}, {"group", c.group},
                                {"tracking", to_string(c.tracking)}});
  }
  stats["fusion_events"] = nlohmann::json::array();
  for (const auto& e : snap.events)
    stats["fusion_events"].push_back({{"time_s", e.wall_time_s}, {"client_a", e.client_a}, {"client_b", e.client_b},
                                      {"group", e.group}, {"inliers", e.inliers}, {"duration_ms", e.duration_ms},
                                      {"kind", e.kind}});
  std::ofstream(dir + "/stats.json") << stats.dump(2) << "\n";
}

}  // namespace cslam
