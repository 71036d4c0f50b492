#pragma once
// Map persistence of cslam-server: loads the newest snapshot of --state-dir at start, and writes
// one every --snapshot-interval seconds from its own thread (and on demand, and at shutdown).
// Each write reads every map under its shared lock for a short copy (CollaborativeSystem::
// export_state), then serialises, checksums and writes crash-safely off the SLAM threads. A
// failed write (full disk) is logged and counted; the previous snapshot stays, SLAM goes on.
#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "server/http/map_routes.h"
#include "server/session_table.h"
#include "system/collaborative_system.h"

namespace cslam::server {

struct StateStoreConfig {
  std::string dir;           // empty: persistence off
  double interval_s = 10.0;  // <= 0: only on demand and at shutdown
  bool reset = false;        // start empty even if the folder holds a snapshot
  std::uint32_t vocabulary_words = 0;
};

struct StateStoreStats {
  std::uint64_t written = 0, failed = 0;
  double last_export_ms = 0, last_encode_ms = 0, last_write_ms = 0;  // lock-holding copy, serialise, file
  std::uint64_t last_bytes = 0;
  // Map copies that gave their lock up to a waiting writer (yields), and that then copied without
  // yielding after 20 such (forced): in the last write, and over all writes.
  std::uint64_t last_yields = 0, last_forced = 0, yields = 0, forced = 0;
  std::string last_error;
  // Health of the writes (steady clock): the last success, and the first failure since it.
  std::optional<std::chrono::steady_clock::time_point> last_success, failing_since;
};

// Seconds since the last successful write (nullopt before the first), and for how long writes
// have been failing (0 when the newest write succeeded or none was tried).
struct SnapshotHealth {
  std::optional<double> last_success_age_s;
  double failing_for_s = 0;
};
SnapshotHealth snapshot_health(const StateStoreStats& stats, std::chrono::steady_clock::time_point now);

class StateStore : public http::MapStore {
 public:
  StateStore(StateStoreConfig config, CollaborativeSystem& system);
  ~StateStore() override;  // stop()

  // Loads the newest snapshot into the system (before any client connects). Throws InputError
  // naming the file if it is unreadable, corrupt or of another version, unless config.reset.
  std::vector<RestoredSession> load();
  void start();  // the periodic writer thread
  void stop();   // idempotent; joins
  // Writes a snapshot on the calling thread; false (logged, counted) on failure.
  bool write();
  // Runs before every snapshot's export, on the writing thread (the dense map's wait_stored).
  // Set before start().
  void set_before_export(std::function<void()> hook) { before_export_ = std::move(hook); }

  // http::MapStore
  std::optional<std::string> snapshot_file() const override;
  std::string write_now(double timeout_s) override;
  std::size_t load(const std::string& name) override;
  std::string stats_json() const override;
  StateStoreStats stats() const;

 private:
  void run();

  const StateStoreConfig config_;
  CollaborativeSystem& system_;
  std::mutex write_mutex_;  // one writer at a time
  std::function<void()> before_export_;
  mutable std::mutex mutex_;
  std::condition_variable cv_, done_cv_;
  bool stop_ = false;
  std::uint64_t requested_ = 0, completed_ = 0;  // on-demand writes
  StateStoreStats stats_;
  std::thread thread_;
};

}  // namespace cslam::server
