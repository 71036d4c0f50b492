#include "dense/trajectory_recon.h"

#include <algorithm>
#include <optional>
#include <thread>

#include "core/bounded_queue.h"
#include "core/error.h"
#include "core/stopwatch.h"
#include "io/tum_dataset.h"

namespace cslam {

namespace {

// One frame to integrate: where its images come from and its pose.
struct Job {
  SE3 T_world_cam;                      // when the colour image was taken
  std::optional<SE3> T_world_depthcam;  // when the depth image was, if known and elsewhere
  const PinholeCamera* camera = nullptr;
  const RgbdPair* pair = nullptr;    // from disk, or
  const TimedRgbd* frame = nullptr;  // in memory
};

struct Loaded {
  const Job* job = nullptr;
  cv::Mat bgr, depth;
  bool ok = true;
};

Loaded load(const Job& job) {
  Loaded l;
  l.job = &job;
  if (job.frame) {
    l.bgr = job.frame->bgr;
    l.depth = job.frame->depth;
    return l;
  }
  try {
    RgbdImages im = load_rgbd(*job.pair);
    l.bgr = std::move(im.bgr);
    l.depth = std::move(im.depth);
  } catch (const InputError&) {
    l.ok = false;  // unreadable file: skipped and counted as a bad image
  }
  return l;
}

DenseResult run_jobs(const std::vector<Job>& jobs, int unmatched, const DenseConfig& config,
                     const DenseProgressCallback& progress) {
  DenseReconstructor recon(config);
  for (int i = 0; i < unmatched; ++i) recon.count_skipped(SkipReason::kNoImage);
  DenseProgress p;
  p.total = int(jobs.size());
  auto consume = [&](const Loaded& l) {
    if (!l.ok)
      recon.count_skipped(SkipReason::kBadImage);
    else if (recon.integrate(l.job->T_world_cam, l.bgr, l.depth, *l.job->camera, l.job->T_world_depthcam).used)
      ++p.used;
    ++p.done;
    if (progress) progress(p);
  };
  if (config.threads >= 2) {
    BoundedQueue<Loaded> queue(4);
    double load_ms = 0;
    std::thread loader([&] {
      for (const Job& job : jobs) {
        Stopwatch sw;
        Loaded l = load(job);
        load_ms += sw.ms();
        if (!queue.push(std::move(l))) break;
      }
      queue.close();
    });
    try {
      while (auto l = queue.pop()) consume(*l);
    } catch (...) {
      queue.close();
      loader.join();
      throw;
    }
    loader.join();
    recon.add_load_time(load_ms);
  } else {
    for (const Job& job : jobs) {
      Stopwatch sw;
      Loaded l = load(job);
      recon.add_load_time(sw.ms());
      consume(l);
    }
  }
  return recon.finish();
}

}  // namespace

PoseFrameMatch match_poses_to_frames(Trajectory poses, const std::vector<double>& frame_times, double max_dt) {
  sort_by_time(poses);
  std::vector<double> pose_times;
  pose_times.reserve(poses.size());
  for (const auto& p : poses) pose_times.push_back(p.timestamp);
  PoseFrameMatch out;
  for (const auto& [i, j] : associate_timestamps(pose_times, frame_times, max_dt))
    out.matches.emplace_back(poses[size_t(i)], j);
  std::sort(out.matches.begin(), out.matches.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
  out.unmatched_poses = int(poses.size() - out.matches.size());
  return out;
}

namespace {

// The camera when a depth image `offset` seconds after the colour image of `pose` was taken:
// `poses` (sorted) interpolated there; nullopt if not asked for, no offset, or no poses around it.
std::optional<SE3> depth_pose(const Trajectory& poses, const StampedPose& pose, double offset,
                              const DenseConfig& config) {
  if (!config.depth_time_compensation || offset == 0) return std::nullopt;
  return interpolate_pose(poses, pose.timestamp + offset);
}

}  // namespace

DenseResult reconstruct_from_trajectories(const std::vector<DatasetPoses>& sources, const DenseConfig& config,
                                          const DenseProgressCallback& progress) {
  config.validate();
  std::vector<TumDataset> datasets;
  datasets.reserve(sources.size());
  std::vector<Job> jobs;
  int unmatched = 0;
  for (const auto& src : sources) {
    src.camera.validate();
    datasets.push_back(open_tum_dataset(src.dataset_dir, config.max_time_gap));
    const TumDataset& ds = datasets.back();
    std::vector<double> times;
    for (const auto& pr : ds.pairs) times.push_back(pr.rgb_time);
    Trajectory sorted = src.poses;
    sort_by_time(sorted);
    const PoseFrameMatch m = match_poses_to_frames(sorted, times, config.max_time_gap);
    unmatched += m.unmatched_poses;
    for (const auto& [pose, idx] : m.matches) {
      Job j;
      j.pair = &ds.pairs[size_t(idx)];
      j.T_world_cam = pose.T_world_cam;
      j.T_world_depthcam = depth_pose(sorted, pose, j.pair->depth_time - j.pair->rgb_time, config);
      j.camera = &src.camera;
      jobs.push_back(j);
    }
  }
  return run_jobs(jobs, unmatched, config, progress);
}

DenseResult reconstruct_from_frames(const std::vector<FramePoses>& sources, const DenseConfig& config,
                                    const DenseProgressCallback& progress) {
  config.validate();
  std::vector<Job> jobs;
  int unmatched = 0;
  for (const auto& src : sources) {
    if (!src.frames) throw std::invalid_argument("reconstruct_from_frames: null frame list");
    src.camera.validate();
    // Frames sorted by time (indices into the caller's list).
    std::vector<int> order(src.frames->size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = int(i);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
      return (*src.frames)[size_t(a)].timestamp < (*src.frames)[size_t(b)].timestamp;
    });
    std::vector<double> times;
    for (int i : order) times.push_back((*src.frames)[size_t(i)].timestamp);
    Trajectory sorted = src.poses;
    sort_by_time(sorted);
    const PoseFrameMatch m = match_poses_to_frames(sorted, times, config.max_time_gap);
    unmatched += m.unmatched_poses;
    for (const auto& [pose, idx] : m.matches) {
      Job j;
      j.frame = &(*src.frames)[size_t(order[size_t(idx)])];
      j.T_world_cam = pose.T_world_cam;
      j.T_world_depthcam = depth_pose(sorted, pose, j.frame->depth_time_offset, config);
      j.camera = &src.camera;
      jobs.push_back(j);
    }
  }
  return run_jobs(jobs, unmatched, config, progress);
}

}  // namespace cslam
