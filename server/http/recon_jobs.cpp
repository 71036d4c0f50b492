#include "server/http/recon_jobs.h"

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <unistd.h>

#include "cloud/ply_io.h"
#include "core/log.h"

namespace cslam::http {

struct ReconJobs::Job {
  std::string id;
  int group = -1;
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  std::atomic<int> done{0}, total{0}, used{0};
  mutable std::mutex mutex;  // guards the fields below
  std::string state = "queued", message;
  double elapsed_s = 0;
  std::size_t points = 0, triangles = 0;
  std::shared_ptr<const std::string> cloud, mesh;
};

namespace {

struct Cancelled {};

// Our PLY writers take a path: write to a private temp file, read it back, remove it.
template <typename Writer>
std::shared_ptr<const std::string> ply_bytes(const std::string& tag, Writer write) {
  const auto path = std::filesystem::temp_directory_path() / ("cslam-http-" + std::to_string(::getpid()) + "-" + tag + ".ply");
  write(path.string());
  std::ifstream in(path, std::ios::binary);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  std::error_code ec;
  std::filesystem::remove(path, ec);
  return std::make_shared<const std::string>(bytes.str());
}

}  // namespace

ReconJobs::~ReconJobs() {
  cancel_ = true;
  for (std::thread& t : threads_)
    if (t.joinable()) t.join();
}

std::optional<std::string> ReconJobs::start(int group, std::vector<DatasetPoses> sources, DenseConfig config) {
  config.validate();  // throws ConfigError (a 400 for the caller)
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& [id, job] : jobs_) {
    std::lock_guard<std::mutex> job_lock(job->mutex);
    if (job->state == "queued" || job->state == "running") return std::nullopt;
  }
  auto job = std::make_shared<Job>();
  job->id = "r" + std::to_string(next_id_++);
  job->group = group;
  jobs_[job->id] = job;
  threads_.emplace_back([this, job, sources = std::move(sources), config]() mutable { run(*job, std::move(sources), config); });
  return job->id;
}

void ReconJobs::run(Job& job, std::vector<DatasetPoses> sources, DenseConfig config) {
  auto log = logger("http");
  {
    std::lock_guard<std::mutex> lock(job.mutex);
    job.state = "running";
  }
  std::string state = "done", message;
  std::shared_ptr<const std::string> cloud, mesh;
  std::size_t points = 0, triangles = 0;
  try {
    const DenseResult result = reconstruct_from_trajectories(sources, config, [&](const DenseProgress& p) {
      job.done = p.done;
      job.total = p.total;
      job.used = p.used;
      if (cancel_) throw Cancelled{};
    });
    points = result.cloud.size();
    triangles = result.mesh.triangles.size();
    if (points == 0) {
      state = "failed";
      message = "no frame could be used (" + std::to_string(result.counts.skipped()) + " skipped)";
    } else {
      cloud = ply_bytes(job.id + "-cloud", [&](const std::string& p) { write_ply(p, result.cloud); });
      if (triangles > 0) mesh = ply_bytes(job.id + "-mesh", [&](const std::string& p) { write_ply_mesh(p, result.mesh); });
      message = std::to_string(result.counts.used) + " frames used, " + std::to_string(points) + " points";
    }
  } catch (const Cancelled&) {
    state = "cancelled";
  } catch (const std::exception& e) {
    state = "failed";
    message = e.what();
  }
  std::lock_guard<std::mutex> lock(job.mutex);
  job.state = state;
  job.message = message;
  job.cloud = cloud;
  job.mesh = mesh;
  job.points = points;
  job.triangles = triangles;
  job.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - job.start).count();
  log->info("reconstruction {} of group {}: {} {}", job.id, job.group, state, message);
}

std::shared_ptr<ReconJobs::Job> ReconJobs::find(const std::string& id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = jobs_.find(id);
  return it == jobs_.end() ? nullptr : it->second;
}

std::optional<ReconJobView> ReconJobs::view(const std::string& id) const {
  const auto job = find(id);
  if (!job) return std::nullopt;
  ReconJobView v;
  v.id = job->id;
  v.group = job->group;
  v.frames_done = job->done;
  v.frames_total = job->total;
  v.frames_used = job->used;
  std::lock_guard<std::mutex> lock(job->mutex);
  v.state = job->state;
  v.message = job->message;
  v.points = job->points;
  v.triangles = job->triangles;
  v.elapsed_s = v.state == "running" || v.state == "queued"
                    ? std::chrono::duration<double>(std::chrono::steady_clock::now() - job->start).count()
                    : job->elapsed_s;
  v.progress = v.state == "done" ? 1.0 : v.frames_total > 0 ? double(v.frames_done) / v.frames_total : 0.0;
  return v;
}

std::vector<ReconJobView> ReconJobs::list() const {
  std::vector<std::string> ids;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [id, job] : jobs_) ids.push_back(id);
  }
  std::vector<ReconJobView> out;
  for (const std::string& id : ids)
    if (auto v = view(id)) out.push_back(*v);
  return out;
}

std::shared_ptr<const std::string> ReconJobs::cloud_ply(const std::string& id) const {
  const auto job = find(id);
  if (!job) return nullptr;
  std::lock_guard<std::mutex> lock(job->mutex);
  return job->cloud;
}

std::shared_ptr<const std::string> ReconJobs::mesh_ply(const std::string& id) const {
  const auto job = find(id);
  if (!job) return nullptr;
  std::lock_guard<std::mutex> lock(job->mutex);
  return job->mesh;
}

}  // namespace cslam::http
