#include "server/http/recon_jobs.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <unordered_set>

#include <opencv2/imgcodecs.hpp>

#include <unistd.h>

#include "cloud/ply_io.h"
#include "core/log.h"
#include "dense/tsdf_volume.h"
#include "io/tum_dataset.h"
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
  std::thread thread;  // joined by expire() or ~ReconJobs, never by itself
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

namespace {

// The surface the request's frames see, measured on a sample of them: up to max_frames depth
// images (evenly spread over the poses) back-projected at about 80 columns into 10 cm cells;
// area = cells x cell^2 (a surface crossing cells obliquely counts a little high, as an estimate
// of memory should). nullopt if no depth image could be read.
std::optional<double> sampled_surface_m2(const std::vector<DatasetPoses>& sources, const DenseConfig& config,
                                         std::size_t max_frames) {
  constexpr double kCell = 0.10;
  std::size_t poses = 0;
  for (const DatasetPoses& s : sources) poses += s.poses.size();
  if (poses == 0) return std::nullopt;
  const std::size_t step = std::max<std::size_t>(1, poses / max_frames);
  std::unordered_set<std::uint64_t> cells;
  std::size_t read = 0, k = 0;
  for (const DatasetPoses& s : sources) {
    std::vector<TimedFile> depth;
    try {
      depth = open_tum_dataset(s.dataset_dir).depth;
    } catch (const std::exception&) {
      continue;
    }
    if (depth.empty()) continue;
    const PinholeCamera& cam = s.camera;
    const int px = std::max(1, cam.width / 80);
    for (const StampedPose& p : s.poses) {
      if (k++ % step != 0 || !p.T_world_cam.is_finite()) continue;
      auto it = std::lower_bound(depth.begin(), depth.end(), p.timestamp,
                                 [](const TimedFile& f, double t) { return f.timestamp < t; });
      if (it == depth.end()) it = std::prev(it);
      else if (it != depth.begin() && p.timestamp - std::prev(it)->timestamp < it->timestamp - p.timestamp) it = std::prev(it);
      if (std::abs(it->timestamp - p.timestamp) > 0.1) continue;
      const cv::Mat d = cv::imread(it->path, cv::IMREAD_UNCHANGED);
      if (d.type() != CV_16UC1 || d.cols != cam.width || d.rows != cam.height) continue;
      ++read;
      for (int v = px / 2; v < d.rows; v += px)
        for (int u = px / 2; u < d.cols; u += px) {
          const double z = cam.depth_from_raw(d.at<std::uint16_t>(v, u));
          if (z < config.min_depth || z > config.max_depth) continue;
          const Eigen::Vector3d w = p.T_world_cam * cam.unproject(u, v, z);
          const auto cell = [](double x) { return std::uint64_t(std::int64_t(std::floor(x / kCell)) & 0x1FFFFF); };
          cells.insert(cell(w.x()) << 42 | cell(w.y()) << 21 | cell(w.z()));
        }
    }
  }
  if (read == 0) return std::nullopt;
  return double(cells.size()) * kCell * kCell;
}

}  // namespace

// The parts of a request's memory. Constants measured with cslam-recon (--threads 1, as the
// server runs) on the synthetic 2 x 60-frame 320x240 scene (docs/security.md, "Reconstruction
// jobs"): about 100 bytes per back-projected point held in a chunk, 120 per filtered cloud point,
// 48 per mesh triangle, a TSDF block (8^3 voxels) over every block_side^2 of surface. The
// estimate came out 1.5-2x above the measured growth at every setting tried.
ReconEstimate estimate_recon_memory(const std::vector<DatasetPoses>& sources, const DenseConfig& config) {
  constexpr double kChunkPointBytes = 100, kCloudPointBytes = 120, kTriangleBytes = 48;
  constexpr std::size_t kSampleFrames = 24;
  // Without readable depth images: each frame's footprint at mid-depth, frames overlapping
  // about this much (the measured scene: 639 m^2 of footprints over 25 m^2 seen).
  constexpr double kFallbackOverlap = 10.0;
  ReconEstimate e;
  const double stride = std::max(1, config.stride);
  const double depth = 0.5 * (config.min_depth + config.max_depth);
  double footprint_sum = 0, largest_image = 0;
  for (const DatasetPoses& s : sources) {
    const PinholeCamera& c = s.camera;
    e.points_per_frame = std::max(e.points_per_frame, std::ceil(c.width / stride) * std::ceil(c.height / stride));
    largest_image = std::max(largest_image, double(c.width) * c.height);
    const double footprint = (c.width / c.fx * depth) * (c.height / c.fy * depth);
    for (const StampedPose& p : s.poses)
      if (p.T_world_cam.is_finite()) ++e.frames, footprint_sum += footprint;
  }
  if (e.frames == 0) return e;
  const auto sampled = sampled_surface_m2(sources, config, kSampleFrames);
  e.surface_m2 = sampled ? *sampled : footprint_sum / kFallbackOverlap;
  const double leaf = config.voxel_size;
  const double cloud_points = std::min(e.surface_m2 / (leaf * leaf), double(e.frames) * e.points_per_frame);
  e.images = 4 * largest_image * 5;  // BGR + 16-bit depth: a decoded pair and the one loading
  e.chunk_points = std::min<double>(std::max(1, config.chunk_frames), double(e.frames)) * e.points_per_frame * kChunkPointBytes;
  e.cloud = cloud_points * kCloudPointBytes;
  e.ply = cloud_points * 15;  // binary: xyz float, rgb
  if (config.build_mesh) {
    const double vs = config.tsdf.voxel_size, block = TsdfVolume::kBlockSide * vs;
    const double band = 1 + 2 * config.tsdf.truncation / block;
    e.tsdf = e.surface_m2 / (block * block) * band * (double(sizeof(TsdfVolume::Block)) + 64);
    const double triangles = 2 * e.surface_m2 / (vs * vs);
    e.mesh = triangles * kTriangleBytes;
    e.ply += triangles * (13 + 0.5 * 15);
  }
  return e;
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

ReconStart ReconJobs::start(int group, ReconFunction reconstruct, ReconEstimate estimate, DenseConfig config) {
  config.validate();  // throws ConfigError (a 400 for the caller)
  ReconStart out;
  out.estimate = estimate;
  expire();
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& [id, job] : jobs_) {
    std::lock_guard<std::mutex> job_lock(job->mutex);
    if (!job->finished()) {
      ++refused_busy_;
      out.outcome = ReconStart::Outcome::kBusy;
      out.message = "a reconstruction is already running (" + id + ")";
      return out;
    }
  }
  if (out.estimate.total_mb() > config_.max_mb) {
    ++refused_over_budget_;
    char buf[96];
    std::snprintf(buf, sizeof buf, "this request would take about %.0f MB, over the %.0f MB budget (--recon-max-mb)",
                  out.estimate.total_mb(), config_.max_mb);
    out.outcome = ReconStart::Outcome::kOverBudget;
    out.message = std::string(buf) + ": " + out.estimate.summary() + "; use a larger voxel or stride, or mesh=0";
    return out;
  }
  auto job = std::make_shared<Job>();
  job->id = "r" + std::to_string(next_id_++);
  job->group = group;
  job->estimate_mb = out.estimate.total_mb();
  jobs_[job->id] = job;
  ++started_;
  Job* raw = job.get();  // outlives the thread: joined before the job leaves jobs_
  job->thread = std::thread([this, raw, reconstruct = std::move(reconstruct), config]() mutable {
    run(*raw, std::move(reconstruct), config);
  });
  out.id = job->id;
  return out;
}

void ReconJobs::run(Job& job, ReconFunction reconstruct, DenseConfig config) {
  auto log = logger("http");
  {
    std::lock_guard<std::mutex> lock(job.mutex);
    job.state = "running";
  }
  const std::function<std::size_t()> probe = config_.memory_probe ? config_.memory_probe : std::function<std::size_t()>(server::resident_bytes);
  const double rss_start = double(probe());
  auto check_memory = [&] {
    const double rss = double(probe());
    if (rss <= 0 || rss_start <= 0) return;
    const double growth_mb = (rss - rss_start) / kMB;
    if (growth_mb > job.peak_growth_mb) job.peak_growth_mb = growth_mb;
    if (growth_mb > config_.max_mb)
      throw OverBudget{"stopped: the server grew " + mb(rss - rss_start) + " during this job, over the " +
                       mb(config_.max_mb * kMB) + " budget (--recon-max-mb); use a larger voxel or stride"};
  };
  std::string state = "done", message;
  std::shared_ptr<const std::string> cloud, mesh;
  std::size_t points = 0, triangles = 0;
  try {
    DenseResult result = reconstruct(config, [&](const DenseProgress& p) {
      job.done = p.done;
      job.total = p.total;
      job.used = p.used;
      if (cancel_) throw Cancelled{};
      check_memory();
    });
    check_memory();  // after the filtering, TSDF and meshing of finish()
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
  } catch (const OverBudget& e) {
    state = "failed";
    message = e.what;
    ++stopped_over_budget_;
  } catch (const std::exception& e) {
    state = "failed";
    message = e.what();
  }
  reconstruct = nullptr;  // frees what the frames' source holds
  {
    std::lock_guard<std::mutex> lock(job.mutex);
    job.state = state;
    job.message = message;
    job.cloud = cloud;
    job.mesh = mesh;
    job.points = points;
    job.triangles = triangles;
    job.finished_at = SteadyClock::now();
    job.elapsed_s = std::chrono::duration<double>(job.finished_at - job.start).count();
  }
  server::release_free_memory();  // a finished job's memory shows as released (tcmalloc keeps freed spans)
  log->info("reconstruction {} of group {}: {} {} (estimate {:.0f} MB, grew {:.0f} MB)", job.id, job.group, state, message,
            job.estimate_mb, job.peak_growth_mb.load());
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
  gone.clear();  // the PLY bytes go here (unless a download still holds them)
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
  v.elapsed_s = job->finished() ? job->elapsed_s : std::chrono::duration<double>(SteadyClock::now() - job->start).count();
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
