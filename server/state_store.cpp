#include "server/state_store.h"

#include <filesystem>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/log.h"
#include "core/stopwatch.h"
#include "core/thread_priority.h"
#include "proto/snapshot_adapter.h"
#include "proto/snapshot_file.h"

namespace cslam::server {

namespace {
auto log() { return logger("state"); }
}  // namespace

StateStore::StateStore(StateStoreConfig config, CollaborativeSystem& system)
    : config_(std::move(config)), system_(system) {}

StateStore::~StateStore() { stop(); }

std::vector<RestoredSession> StateStore::load() {
  std::vector<RestoredSession> sessions;
  if (config_.dir.empty()) return sessions;
  const auto path = snapshot::newest_snapshot(config_.dir);
  if (!path) {
    log()->info("state folder {}: no snapshot yet, starting empty", config_.dir);
    return sessions;
  }
  if (config_.reset) {
    log()->warn("--state-reset: starting empty; the next snapshot replaces {}", *path);
    return sessions;
  }
  Stopwatch sw;
  SystemState state = snapshot::read_file(*path);
  system_.restore_state(state, *path);
  for (const auto& c : state.clients) sessions.push_back({c.info, c.last_seq, ""});
  log()->info("loaded {} ({} clients) in {:.0f} ms", *path, state.clients.size(), sw.ms());
  return sessions;
}

void StateStore::start() {
  if (config_.dir.empty() || thread_.joinable()) return;
  thread_ = std::thread([this] { run(); });
}

void StateStore::stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  done_cv_.notify_all();
}

void StateStore::run() {
  name_current_thread("snapshot");
  std::unique_lock<std::mutex> lock(mutex_);
  auto next = std::chrono::steady_clock::now() + std::chrono::duration<double>(config_.interval_s);
  for (;;) {
    auto wake = [&] { return stop_ || requested_ > completed_; };
    if (config_.interval_s > 0)
      cv_.wait_until(lock, next, wake);
    else
      cv_.wait(lock, wake);
    if (stop_) return;
    const std::uint64_t serving = requested_;
    lock.unlock();
    write();
    lock.lock();
    completed_ = std::max(completed_, serving);
    done_cv_.notify_all();
    next = std::chrono::steady_clock::now() + std::chrono::duration<double>(config_.interval_s);
  }
}

bool StateStore::write() {
  if (config_.dir.empty()) return false;
  std::lock_guard<std::mutex> writer(write_mutex_);
  if (before_export_) before_export_();
  Stopwatch sw;
  try {
    const SystemState state = system_.export_state();
    const double export_ms = sw.ms();
    sw.reset();
    snapshot::EncodeOptions options;
    options.producer = "cslam-server";
    options.vocabulary_words = config_.vocabulary_words;
    const std::string bytes = snapshot::encode(state, options);
    const double encode_ms = sw.ms();
    sw.reset();
    snapshot::write_atomic(config_.dir, bytes);
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.written;
    stats_.last_export_ms = export_ms;
    stats_.last_encode_ms = encode_ms;
    stats_.last_write_ms = sw.ms();
    stats_.last_bytes = bytes.size();
    stats_.last_yields = stats_.last_forced = 0;
    for (const auto& c : state.clients)
      for (const auto& m : c.maps) {
        stats_.last_yields += std::uint64_t(m.export_yields);
        stats_.last_forced += m.export_forced ? 1 : 0;
      }
    stats_.yields += stats_.last_yields;
    stats_.forced += stats_.last_forced;
    stats_.last_error.clear();
    stats_.last_success = std::chrono::steady_clock::now();
    stats_.failing_since.reset();
    log()->debug("snapshot {}: {} clients, {:.1f} MB (copy {:.1f} ms, encode {:.1f} ms, write {:.1f} ms)",
                 snapshot::current_path(config_.dir), state.clients.size(), double(bytes.size()) / 1e6, export_ms,
                 encode_ms, stats_.last_write_ms);
    return true;
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.failed;
    stats_.last_error = e.what();
    if (!stats_.failing_since) stats_.failing_since = std::chrono::steady_clock::now();
    log()->error("snapshot not written, the previous one is kept ({} failures so far): {}", stats_.failed, e.what());
    return false;
  }
}

std::optional<std::string> StateStore::snapshot_file() const {
  if (config_.dir.empty()) return std::nullopt;
  const std::string p = snapshot::current_path(config_.dir);
  return std::filesystem::exists(p) ? std::optional<std::string>(p) : std::nullopt;
}

std::string StateStore::write_now(double timeout_s) {
  if (config_.dir.empty()) return "the server runs without --state-dir";
  std::unique_lock<std::mutex> lock(mutex_);
  if (!thread_.joinable() || stop_) return "the snapshot writer is not running";
  const std::uint64_t ticket = ++requested_;
  const std::uint64_t failed_before = stats_.failed;
  cv_.notify_all();
  if (!done_cv_.wait_for(lock, std::chrono::duration<double>(timeout_s), [&] { return completed_ >= ticket || stop_; }))
    return "still running";
  if (stats_.failed != failed_before) return stats_.last_error;
  return completed_ >= ticket ? "" : "the server is stopping";
}

std::size_t StateStore::load(const std::string& name) {
  if (config_.dir.empty()) throw InputError(name, "the server runs without --state-dir");
  if (name.empty() || name.find('/') != std::string::npos || name.find('\\') != std::string::npos || name[0] == '.')
    throw InputError(name, "a plain file name inside " + config_.dir + "/import is required");
  const std::string path = (std::filesystem::path(config_.dir) / "import" / name).string();
  const SystemState state = snapshot::read_file(path);
  system_.restore_state(state, path);
  log()->info("loaded {} clients from {}", state.clients.size(), path);
  return state.clients.size();
}

StateStoreStats StateStore::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

SnapshotHealth snapshot_health(const StateStoreStats& stats, std::chrono::steady_clock::time_point now) {
  SnapshotHealth h;
  if (stats.last_success) h.last_success_age_s = std::chrono::duration<double>(now - *stats.last_success).count();
  if (stats.failing_since) h.failing_for_s = std::chrono::duration<double>(now - *stats.failing_since).count();
  return h;
}

std::string StateStore::stats_json() const {
  const StateStoreStats s = stats();
  const SnapshotHealth health = snapshot_health(s, std::chrono::steady_clock::now());
  nlohmann::json j = {
      {"state_dir", config_.dir},
      {"interval_s", config_.interval_s},
      {"written", s.written},
      {"failed", s.failed},
      {"last_copy_ms", s.last_export_ms},
      {"last_encode_ms", s.last_encode_ms},
      {"last_write_ms", s.last_write_ms},
      {"last_bytes", s.last_bytes},
      {"last_copy_yields", s.last_yields},
      {"last_copy_forced", s.last_forced},
      {"copy_yields", s.yields},
      {"copy_forced", s.forced},
      {"last_error", s.last_error},
      {"last_success_age_s", health.last_success_age_s ? nlohmann::json(*health.last_success_age_s) : nlohmann::json()},
      {"failing_for_s", health.failing_for_s}};
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);  // last_error may hold a path's bytes
}

}  // namespace cslam::server
