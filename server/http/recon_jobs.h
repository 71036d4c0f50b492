#pragma once
// Asynchronous dense reconstructions started over HTTP: one thread per job (at most one running
// at a time, so SLAM keeps its cores), progress published through atomics, results kept in memory
// as PLY bytes. Threads are joined on destruction (a running job is cancelled at its next frame).
#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "dense/trajectory_recon.h"

namespace cslam::http {

struct ReconJobView {
  std::string id;
  int group = -1;
  std::string state;  // queued, running, done, failed, cancelled
  double progress = 0;  // 0..1
  int frames_done = 0, frames_total = 0, frames_used = 0;
  std::size_t points = 0, triangles = 0;
  std::string message;
  double elapsed_s = 0;
};

class ReconJobs {
 public:
  ReconJobs() = default;
  ~ReconJobs();  // cancels and joins every job thread
  ReconJobs(const ReconJobs&) = delete;
  ReconJobs& operator=(const ReconJobs&) = delete;

  // Starts a job; returns its id, or nullopt if another job is still running.
  std::optional<std::string> start(int group, std::vector<DatasetPoses> sources, DenseConfig config);
  std::optional<ReconJobView> view(const std::string& id) const;
  std::vector<ReconJobView> list() const;
  // PLY bytes of a finished job (nullptr if unknown, not finished or no mesh).
  std::shared_ptr<const std::string> cloud_ply(const std::string& id) const;
  std::shared_ptr<const std::string> mesh_ply(const std::string& id) const;

 private:
  struct Job;
  void run(Job& job, std::vector<DatasetPoses> sources, DenseConfig config);
  std::shared_ptr<Job> find(const std::string& id) const;

  mutable std::mutex mutex_;
  std::map<std::string, std::shared_ptr<Job>> jobs_;
  std::vector<std::thread> threads_;
  int next_id_ = 1;
  std::atomic<bool> cancel_{false};
};

}  // namespace cslam::http
