#pragma once
// The server's live dense map: keyframes' images as received go into the keyframe store, and one
// worker thread keeps a LiveDenseMap (TSDF submaps) in step with the SLAM maps' current keyframe
// poses. SLAM workers only queue (on_keyframe); the worker stores, integrates, follows
// corrections and publishes an immutable view for HTTP. Bounded everywhere: the queue (keyframes
// beyond it are counted and left to the store-less path: never silently), the store
// (--dense-store-max-mb: new keyframes' images refused when full, counted), the work per step.
#include <atomic>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "dense/live_dense_map.h"
#include "server/dense/keyframe_store.h"
#include "system/collaborative_system.h"

namespace cslam::server {

struct DenseServiceConfig {
  bool enabled = true;
  LiveDenseConfig map;
  KeyframeStoreConfig store;         // dir: --state-dir/dense, or a private temporary folder
  bool store_is_temporary = false;   // removed at exit
  double step_interval_s = 0.25;     // poses are re-read at least this often
  std::size_t queue_capacity = 512;  // keyframes waiting for the worker (their received bytes, ~0.1 MB each)
  std::size_t queue_decoded = 16;    // ... of which the first ones also keep their decoded images
  int max_integrations_per_step = 2;
  int max_reintegrations_per_step = 1;
  double log_interval_s = 5;
  void validate() const;  // throws ConfigError
};

struct DenseServiceStats {
  std::uint64_t keyframes_received = 0, queue_dropped = 0, encoded_here = 0;
  std::uint64_t stored = 0, store_refused_full = 0, store_errors = 0, culled = 0;
  std::uint64_t integrated = 0, reintegrated = 0, moved = 0, missing_images = 0, steps = 0;
  std::size_t queue = 0, pending = 0, submaps = 0;
  std::vector<double> integrate_ms;  // the last few hundred keyframes
  double last_step_ms = 0, integrate_cpu_ms = 0;
  // When the last correction (a submap moved or was rebuilt) was applied, seconds since start.
  double last_correction_s = -1;
  KeyframeStoreStats store;
};

class DenseService {
 public:
  // Opens the store (throws InputError/ConfigError with a clear message if it cannot be used).
  DenseService(DenseServiceConfig config, const CollaborativeSystem& system);
  ~DenseService();  // stop()
  DenseService(const DenseService&) = delete;
  DenseService& operator=(const DenseService&) = delete;

  // Keeps only the stored keyframes the SLAM maps hold now (the restored snapshot) and queues
  // them for integration; starts the worker.
  void start();
  // SystemConfig::on_keyframe (SLAM worker threads): queue and return.
  void on_keyframe(const ClientInfo& client, const KeyFrameId& id, const RgbdFrame& frame, const SE3& T_cam_depthcam);
  // Stops the worker after storing what is queued and integrating every pending keyframe with
  // the final poses. Idempotent.
  void finish();
  // Waits (up to timeout_s) until every keyframe queued so far has been written to the keyframe
  // store (or refused, counted). The map snapshot calls it first, so that a snapshot never holds a
  // keyframe whose images the store has not got yet merely because this low-priority worker lags.
  // False on timeout (logged).
  bool wait_stored(double timeout_s);

  std::shared_ptr<const DenseMapView> view() const { return map_.view(); }
  // For other threads (a full-rate reconstruction job): a group's live keyframes at their current
  // poses, and one keyframe's stored images decoded with its client's camera (nullopt: not stored,
  // or unreadable, logged).
  std::vector<KeyframePose> group_keyframes(int group) const;
  struct StoredKeyframe {
    DenseImages images;
    PinholeCamera camera;
    double depth_time_offset = 0;
  };
  std::optional<StoredKeyframe> stored_keyframe(KeyFrameId id) const;
  DenseServiceStats stats() const;
  const DenseServiceConfig& config() const { return config_; }
  double uptime_s() const;

 private:
  static constexpr int kUnclaimed = 0, kStoring = 1, kStored = 2;
  struct Job {
    ClientInfo client;
    KeyframeRecord record;
    std::optional<DenseImages> images;
    SE3 T_cam_depthcam;  // motion between the colour and the depth image (not stored: identity after a restart)
    // Who stores it: the worker, or wait_stored on the snapshot thread, whichever claims it first.
    std::atomic<int> store_state{kUnclaimed};
  };
  void run();
  // Claims the job and writes its images (and its client's camera) to the store; false if
  // another thread claimed it first. Either thread may call it.
  bool put_job(Job& job);
  void integrate_jobs(std::vector<std::shared_ptr<Job>>& jobs);  // the worker's
  void step(bool final);
  std::optional<DenseImages> load(KeyFrameId id);
  // A stored keyframe decoded with the given camera (nullopt: not stored or unreadable, logged).
  std::optional<StoredKeyframe> decode_stored(KeyFrameId id, const PinholeCamera& camera) const;
  void log_progress();

  const DenseServiceConfig config_;
  const CollaborativeSystem& system_;
  KeyframeStore store_;
  LiveDenseMap map_;                                 // the worker's alone
  std::map<ClientId, PinholeCamera> cameras_;        // the worker's alone
  std::mutex camera_mutex_;                          // store_cameras_
  std::map<ClientId, PinholeCamera> store_cameras_;  // cameras written to the store by put_job
  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point last_log_ = start_;

  mutable std::mutex mutex_;  // queue_, stop_, stats_
  std::condition_variable wake_;
  std::condition_variable stored_cv_;       // the worker stored a batch (wait_stored)
  std::deque<std::shared_ptr<Job>> queue_;  // each left here until stored (wait_stored sees it)
  bool stop_ = false, finished_ = false;
  DenseServiceStats stats_;
  std::thread thread_;
};

}  // namespace cslam::server
