#include "server/http/recon_jobs.h"

#include <algorithm>
#include <cstdio>

#include "cloud/ply_io.h"
#include "core/log.h"
#include "core/thread_priority.h"
#include "server/heap.h"

namespace cslam::http {

using SteadyClock = std::chrono::steady_clock;

struct ReconJobs::Job {
  std::string id;
  int group = -1;
  SteadyClock::time_point start = SteadyClock::now(), finished_at{};
  std::atomic<int> done{0}, total{0}, used{0};
  std::atomic<double> peak_growth_mb{0};
  double estimate_mb = 0;
  std::thread thread;        // joined by expire() or ~ReconJobs, never by itself
  mutable std::mutex mutex;  // guards the fields below
  std::string state = "queued", message;
  double elapsed_s = 0;
  std::size_t points = 0, triangles = 0;
  std::shared_ptr<const std::string> cloud, mesh;
  bool finished() const { return state != "queued" && state != "running"; }
  std::size_t bytes_held() const { return (cloud ? cloud->size() : 0) + (mesh ? mesh->size() : 0); }
};

namespace {

struct Cancelled {};
struct OverBudget {
  std::string what;
};

constexpr double kMB = 1024.0 * 1024.0;

std::string mb(double bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.0f MB", bytes / kMB);
  return buf;
}

}  // namespace

std::string ReconEstimate::summary() const {
  return "images " + mb(images) + ", point chunks " + mb(chunk_points) + ", cloud " + mb(cloud) + ", TSDF " + mb(tsdf) +
         ", mesh " + mb(mesh) + ", PLY " + mb(ply);
}

ReconJobs::ReconJobs(ReconJobsConfig config) : config_(config) {}

ReconJobs::~ReconJobs() {
  cancel_ = true;
  std::map<std::string, std::shared_ptr<Job>> jobs;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    jobs.swap(jobs_);
  }
  for (auto& [id, job] : jobs)
    if (job->thread.joinable()) job->thread.join();
}

ReconStart ReconJobs::start(int group, std::vector<DatasetPoses> sources, DenseConfig config) {
  config.validate();  // throws ConfigError (a 400 for the caller)
  ReconEstimate estimate = estimate_recon_memory(sources, config);
  auto shared = std::make_shared<std::vector<DatasetPoses>>(std::move(sources));
  ReconFunction reconstruct = [shared](const DenseConfig& c, const DenseProgressCallback& progress) {
    return reconstruct_from_trajectories(*shared, c, progress);
  };
  return start(group, std::move(reconstruct), estimate, std::move(config));
}

bool ReconJobs::refused_locked(ReconStart& out) {
  for (const auto& [id, job] : jobs_) {
    std::lock_guard<std::mutex> job_lock(job->mutex);
    if (!job->finished()) {
      ++refused_busy_;
      out.outcome = ReconStart::Outcome::kBusy;
      out.message = "a reconstruction is already running (" + id + ")";
      return true;
    }
  }
  if (!(out.estimate.total_mb() > config_.max_mb)) return false;
  ++refused_over_budget_;
  char buf[96];
  std::snprintf(buf, sizeof buf, "this request would take about %.0f MB, over the %.0f MB budget (--recon-max-mb)",
                out.estimate.total_mb(), config_.max_mb);
  out.outcome = ReconStart::Outcome::kOverBudget;
  out.message = std::string(buf) + ": " + out.estimate.summary() + "; use a larger voxel or stride, or mesh=0";
  return true;
}

ReconStart ReconJobs::start(int group, ReconFunction reconstruct, ReconEstimate estimate, DenseConfig config) {
  config.validate();  // throws ConfigError (a 400 for the caller)
  ReconStart out;
  out.estimate = estimate;
  expire();
  std::lock_guard<std::mutex> lock(mutex_);
  if (refused_locked(out)) return out;
  auto job = std::make_shared<Job>();
  job->id = "r" + std::to_string(next_id_++);
  job->group = group;
  job->estimate_mb = out.estimate.total_mb();
  jobs_[job->id] = job;
  ++started_;
  Job* raw = job.get();  // outlives the thread: joined before the job leaves jobs_
  job->thread = std::thread([this, raw, reconstruct = std::move(reconstruct), config]() mutable {
    name_current_thread("recon-job");
    run(*raw, std::move(reconstruct), config);
  });
  out.id = job->id;
  return out;
}

struct ReconJobs::Outcome {
  std::string state = "done", message;
  std::shared_ptr<const std::string> cloud, mesh;
  std::size_t points = 0, triangles = 0;
};

namespace {

// Watches the process's growth since construction: records the peak, throws OverBudget past max_mb.
class MemoryWatch {
 public:
  MemoryWatch(std::function<std::size_t()> probe, double max_mb, std::atomic<double>& peak_growth_mb)
      : probe_(std::move(probe)), start_(double(probe_())), max_mb_(max_mb), peak_growth_mb_(peak_growth_mb) {}
  void check() const {
    const double rss = double(probe_());
    if (rss <= 0 || start_ <= 0) return;
    const double growth_mb = (rss - start_) / kMB;
    if (growth_mb > peak_growth_mb_) peak_growth_mb_ = growth_mb;
    if (growth_mb > max_mb_)
      throw OverBudget{"stopped: the server grew " + mb(rss - start_) + " during this job, over the " +
                       mb(max_mb_ * kMB) + " budget (--recon-max-mb); use a larger voxel or stride"};
  }

 private:
  std::function<std::size_t()> probe_;
  double start_;
  double max_mb_;
  std::atomic<double>& peak_growth_mb_;
};

}  // namespace

void ReconJobs::keep_products(const Job& job, const DenseResult& result, Outcome& out) {
  out.points = result.cloud.size();
  out.triangles = result.mesh.triangles.size();
  if (out.points == 0) {
    out.state = "failed";
    out.message = "no frame could be used (" + std::to_string(result.counts.skipped()) + " skipped)";
    return;
  }
  out.cloud = std::make_shared<const std::string>(ply_bytes(result.cloud));  // in memory: no temp files
  if (out.triangles > 0) out.mesh = std::make_shared<const std::string>(ply_mesh_bytes(result.mesh));
  out.message = std::to_string(result.counts.used) + " frames used, " + std::to_string(out.points) + " points";
}

ReconJobs::Outcome ReconJobs::execute(Job& job, const ReconFunction& reconstruct, const DenseConfig& config) {
  const MemoryWatch memory(
      config_.memory_probe ? config_.memory_probe : std::function<std::size_t()>(server::resident_bytes),
      config_.max_mb, job.peak_growth_mb);
  Outcome out;
  try {
    DenseResult result = reconstruct(config, [&](const DenseProgress& p) {
      job.done = p.done;
      job.total = p.total;
      job.used = p.used;
      if (cancel_) throw Cancelled{};
      memory.check();
    });
    memory.check();  // after the filtering, TSDF and meshing of finish()
    keep_products(job, result, out);
  } catch (const Cancelled&) {
    out.state = "cancelled";
  } catch (const OverBudget& e) {
    out.state = "failed";
    out.message = e.what;
    ++stopped_over_budget_;
  } catch (const std::exception& e) {
    out.state = "failed";
    out.message = e.what();
  }
  return out;
}

void ReconJobs::run(Job& job, ReconFunction reconstruct, DenseConfig config) {
  {
    std::lock_guard<std::mutex> lock(job.mutex);
    job.state = "running";
  }
  const Outcome out = execute(job, reconstruct, config);
  reconstruct = nullptr;  // frees what the frames' source holds
  {
    std::lock_guard<std::mutex> lock(job.mutex);
    job.state = out.state;
    job.message = out.message;
    job.cloud = out.cloud;
    job.mesh = out.mesh;
    job.points = out.points;
    job.triangles = out.triangles;
    job.finished_at = SteadyClock::now();
    job.elapsed_s = std::chrono::duration<double>(job.finished_at - job.start).count();
  }
  server::release_free_memory();  // a finished job's memory shows as released (tcmalloc keeps freed spans)
  logger("http")->info("reconstruction {} of group {}: {} {} (estimate {:.0f} MB, grew {:.0f} MB)", job.id, job.group,
                       out.state, out.message, job.estimate_mb, job.peak_growth_mb.load());
}

std::vector<std::shared_ptr<ReconJobs::Job>> ReconJobs::expire_locked(SteadyClock::time_point now) {
  struct Finished {
    SteadyClock::time_point at;
    std::string id;
    std::size_t bytes;
    bool operator<(const Finished& o) const { return at < o.at; }
  };
  std::vector<Finished> finished;
  double held = 0;
  for (const auto& [id, job] : jobs_) {
    std::lock_guard<std::mutex> job_lock(job->mutex);
    if (!job->finished()) continue;
    finished.push_back({job->finished_at, id, job->bytes_held()});
    held += double(job->bytes_held());
  }
  std::sort(finished.begin(), finished.end());  // oldest first
  std::vector<std::shared_ptr<Job>> out;
  for (std::size_t i = 0; i < finished.size(); ++i) {
    const bool too_many = finished.size() - i > config_.max_finished;
    const bool too_old = std::chrono::duration<double>(now - finished[i].at).count() > config_.max_age_s;
    const bool too_big = held > config_.max_held_mb * kMB;
    if (!too_many && !too_old && !too_big) continue;
    held -= double(finished[i].bytes);
    auto it = jobs_.find(finished[i].id);
    out.push_back(it->second);
    jobs_.erase(it);
    ++expired_;
  }
  return out;
}

void ReconJobs::expire() {
  std::vector<std::shared_ptr<Job>> gone;
  std::vector<std::thread> ended;  // threads of finished jobs kept for download
  {
    std::lock_guard<std::mutex> lock(mutex_);
    gone = expire_locked(SteadyClock::now());
    for (auto& [id, job] : jobs_) {
      std::lock_guard<std::mutex> job_lock(job->mutex);
      if (job->finished() && job->thread.joinable()) ended.push_back(std::move(job->thread));
    }
  }
  // A job publishes its state before its thread's last steps (freeing memory, a log line): join
  // now, so that every finished job's thread is gone once expire() returns.
  for (std::thread& t : ended) t.join();
  if (gone.empty()) return;
  for (auto& job : gone)
    if (job->thread.joinable()) job->thread.join();  // finished: returns at once
  gone.clear();                                      // the PLY bytes go here (unless a download still holds them)
  server::release_free_memory();  // a finished job's memory shows as released (tcmalloc keeps freed spans)
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
  v.estimate_mb = job->estimate_mb;
  v.peak_growth_mb = job->peak_growth_mb;
  std::lock_guard<std::mutex> lock(job->mutex);
  v.state = job->state;
  v.message = job->message;
  v.points = job->points;
  v.triangles = job->triangles;
  v.bytes_held = job->bytes_held();
  v.elapsed_s =
      job->finished() ? job->elapsed_s : std::chrono::duration<double>(SteadyClock::now() - job->start).count();
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

ReconStats ReconJobs::stats() const {
  ReconStats s;
  std::lock_guard<std::mutex> lock(mutex_);
  s.jobs = jobs_.size();
  for (const auto& [id, job] : jobs_) {
    std::lock_guard<std::mutex> job_lock(job->mutex);
    s.running += !job->finished();
    s.bytes_held += job->bytes_held();
  }
  s.started = started_;
  s.expired = expired_;
  s.refused_busy = refused_busy_;
  s.refused_over_budget = refused_over_budget_;
  s.stopped_over_budget = stopped_over_budget_;
  s.max_mb = config_.max_mb;
  return s;
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
