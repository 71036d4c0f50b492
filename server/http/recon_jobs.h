#pragma once
// Asynchronous dense reconstructions started over HTTP: one thread per job (at most one running
// at a time, so SLAM keeps its cores), progress published through atomics, results kept in memory
// as PLY bytes. Bounded (docs/security.md, "Reconstruction jobs"):
//  - a request's memory is estimated before it starts (estimate_recon_memory) and refused over
//    ReconJobsConfig::max_mb; while it runs, the process's resident memory may grow at most
//    max_mb past its level at the start, else the job stops ("failed", with the figures);
//  - finished jobs expire by count (max_finished), age (max_age_s) and the bytes they hold
//    together (max_held_mb); their threads are joined and their bytes freed (and given back to
//    the system);
//  - the bytes held by finished jobs are shown per job and in stats().
// Threads are joined on destruction (a running job is cancelled at its next frame).
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "dense/trajectory_recon.h"

namespace cslam::http {

struct ReconJobsConfig {
  double max_mb = 768;           // one request's memory budget (estimate and actual growth), MB
  std::size_t max_finished = 8;  // finished jobs kept; the oldest beyond are dropped
  double max_age_s = 900;        // a finished job is dropped this long after it finished
  double max_held_mb = 256;      // PLY bytes finished jobs may hold together; the oldest go first
  // The process's resident bytes, read before a job and at each of its frames (empty:
  // resident_bytes(); tests give their own).
  std::function<std::size_t()> memory_probe;
};

// What a request would take, by part (bytes). An estimate meant to err high on the scenes
// measured (docs/security.md gives its accuracy); the running check is the backstop.
struct ReconEstimate {
  std::size_t frames = 0;       // poses of the request (at most one frame each)
  double points_per_frame = 0;  // pixels at the stride
  double surface_m2 = 0;        // surface the frames can see (capped by the scene extent)
  double images = 0, chunk_points = 0, cloud = 0, tsdf = 0, mesh = 0, ply = 0;
  double total_bytes() const { return images + chunk_points + cloud + tsdf + mesh + ply; }
  double total_mb() const { return total_bytes() / (1024.0 * 1024.0); }
  std::string summary() const;  // "cloud 12 MB, TSDF 300 MB, ..."
};
ReconEstimate estimate_recon_memory(const std::vector<DatasetPoses>& sources, const DenseConfig& config);

// A reconstruction whose frames come from elsewhere (the server's keyframe store): runs on the
// job's thread; the progress callback may throw to stop it.
using ReconFunction = std::function<DenseResult(const DenseConfig&, const DenseProgressCallback&)>;

struct ReconJobView {
  std::string id;
  int group = -1;
  std::string state;    // queued, running, done, failed, cancelled
  double progress = 0;  // 0..1
  int frames_done = 0, frames_total = 0, frames_used = 0;
  std::size_t points = 0, triangles = 0;
  std::string message;
  double elapsed_s = 0;
  double estimate_mb = 0;      // estimate_recon_memory before it started
  double peak_growth_mb = 0;   // largest resident-memory growth seen while it ran
  std::size_t bytes_held = 0;  // PLY bytes kept for download
};

struct ReconStats {
  std::size_t jobs = 0, running = 0;  // kept now
  std::uint64_t started = 0, expired = 0, refused_busy = 0, refused_over_budget = 0, stopped_over_budget = 0;
  std::size_t bytes_held = 0;
  double max_mb = 0;
};

struct ReconStart {
  enum class Outcome { kStarted, kBusy, kOverBudget };
  Outcome outcome = Outcome::kStarted;
  std::string id;  // kStarted
  ReconEstimate estimate;
  std::string message;  // kBusy / kOverBudget: why
};

class ReconJobs {
 public:
  explicit ReconJobs(ReconJobsConfig config = {});
  ~ReconJobs();  // cancels and joins every job thread
  ReconJobs(const ReconJobs&) = delete;
  ReconJobs& operator=(const ReconJobs&) = delete;

  // Estimates and starts a job; refuses while another runs or over the budget. Throws
  // ConfigError on a bad config.
  ReconStart start(int group, std::vector<DatasetPoses> sources, DenseConfig config);
  // The same for frames from elsewhere, with the caller's estimate.
  ReconStart start(int group, ReconFunction reconstruct, ReconEstimate estimate, DenseConfig config);
  std::optional<ReconJobView> view(const std::string& id) const;
  std::vector<ReconJobView> list() const;
  ReconStats stats() const;
  // PLY bytes of a finished job (nullptr if unknown, not finished or no mesh).
  std::shared_ptr<const std::string> cloud_ply(const std::string& id) const;
  std::shared_ptr<const std::string> mesh_ply(const std::string& id) const;
  // Drops finished jobs past the count and age limits (joins their threads); also done by start().
  void expire();
  const ReconJobsConfig& config() const { return config_; }

 private:
  struct Job;
  struct Outcome;                                                     // what a job ends with: state, message, products
  void run(Job& job, ReconFunction reconstruct, DenseConfig config);  // the job's thread
  Outcome execute(Job& job, const ReconFunction& reconstruct, const DenseConfig& config);
  static void keep_products(const Job& job, const DenseResult& result, Outcome& out);
  bool refused_locked(ReconStart& out);  // busy, or out.estimate over the budget: out says why
  std::shared_ptr<Job> find(const std::string& id) const;
  std::vector<std::shared_ptr<Job>> expire_locked(std::chrono::steady_clock::time_point now);

  const ReconJobsConfig config_;
  mutable std::mutex mutex_;  // guards jobs_, next_id_ and the counters below
  std::map<std::string, std::shared_ptr<Job>> jobs_;
  int next_id_ = 1;
  std::uint64_t started_ = 0, expired_ = 0, refused_busy_ = 0, refused_over_budget_ = 0;
  std::atomic<std::uint64_t> stopped_over_budget_{0};
  std::atomic<bool> cancel_{false};
};

}  // namespace cslam::http
