#include "dense/reconstructor.h"

#include <cmath>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include "cloud/filters.h"
#include "core/bounded_queue.h"
#include "core/error.h"
#include "core/log.h"
#include "core/stopwatch.h"
#include "dense/backproject.h"
#include "dense/tsdf_volume.h"
#include "dense/voxel_accumulator.h"

namespace cslam {

const char* to_string(SkipReason r) {
  switch (r) {
    case SkipReason::kNone:
      return "used";
    case SkipReason::kNoImage:
      return "no image within the time gap";
    case SkipReason::kBadPose:
      return "non-finite pose";
    case SkipReason::kBadImage:
      return "empty, unreadable or wrong-type image";
    case SkipReason::kWrongImageSize:
      return "image size differs from the camera";
    case SkipReason::kNoValidDepth:
      return "no valid depth";
  }
  return "?";
}

void DenseCounts::add(SkipReason r) {
  switch (r) {
    case SkipReason::kNone:
      ++used;
      break;
    case SkipReason::kNoImage:
      ++no_image;
      break;
    case SkipReason::kBadPose:
      ++bad_pose;
      break;
    case SkipReason::kBadImage:
      ++bad_image;
      break;
    case SkipReason::kWrongImageSize:
      ++wrong_size;
      break;
    case SkipReason::kNoValidDepth:
      ++no_valid_depth;
      break;
  }
}

void DenseConfig::validate() const {
  if (!(min_depth >= 0) || !(max_depth > min_depth)) throw ConfigError("dense: need 0 <= min_depth < max_depth");
  if (stride < 1) throw ConfigError("dense: stride must be >= 1");
  if (!(voxel_size > 0)) throw ConfigError("dense: voxel_size must be positive");
  if (chunk_frames < 1) throw ConfigError("dense: chunk_frames must be >= 1");
  if (threads < 1) throw ConfigError("dense: threads must be >= 1");
  if (!(max_time_gap >= 0)) throw ConfigError("dense: max_time_gap must be >= 0");
  if (remove_outliers && (outliers.mean_k < 1 || !(outliers.stddev_mul > 0)))
    throw ConfigError("dense: outlier mean_k >= 1 and stddev_mul > 0 required");
}

struct DenseReconstructor::Impl {
  DenseConfig config;
  DenseCounts counts;
  DenseTiming timing;
  std::vector<std::unique_ptr<RayTable>> ray_tables;  // one per distinct camera
  ColoredCloud chunk;
  int chunk_frames = 0;
  VoxelAccumulator accumulator;
  std::optional<TsdfVolume> tsdf;
  // Filter stage: with threads >= 2, that many workers filter chunks concurrently (PCL) and
  // merge them into the accumulator one at a time.
  BoundedQueue<ColoredCloud> chunks;
  std::vector<std::thread> filter_threads;
  std::mutex merge_mutex;  // guards accumulator between the filter workers
  bool finished = false;
  std::set<SkipReason> warned;
  Stopwatch wall;

  explicit Impl(const DenseConfig& c) : config(c), accumulator(c.voxel_size), chunks(size_t(c.threads)) {
    if (config.build_mesh) tsdf.emplace(config.tsdf);
    if (config.threads >= 2)
      for (int k = 0; k < config.threads; ++k)
        filter_threads.emplace_back([this] {
          while (auto c = chunks.pop()) {
            Stopwatch sw;
            const ColoredCloud filtered = accumulator.filter_chunk(*c);
            const double ms = sw.ms();
            std::lock_guard<std::mutex> lock(merge_mutex);
            accumulator.merge(filtered, c->size(), ms);
          }
        });
  }

  ~Impl() { stop_filter_thread(); }

  void stop_filter_thread() {
    chunks.close();
    for (auto& t : filter_threads)
      if (t.joinable()) t.join();
    filter_threads.clear();
  }

  const RayTable& rays_for(const PinholeCamera& camera) {
    for (const auto& t : ray_tables)
      if (same_projection(t->camera(), camera)) return *t;
    ray_tables.push_back(std::make_unique<RayTable>(camera));
    return *ray_tables.back();
  }

  void flush_chunk() {
    if (chunk.empty()) return;
    if (!filter_threads.empty())
      chunks.push(std::move(chunk));
    else
      accumulator.add_chunk(chunk);
    chunk = ColoredCloud();
    chunk_frames = 0;
  }

  void reserve_chunk(const PinholeCamera& camera) {
    const size_t per_frame = size_t((camera.width + config.stride - 1) / config.stride) *
                             size_t((camera.height + config.stride - 1) / config.stride);
    const size_t need = chunk.size() + per_frame;
    if (chunk.points.capacity() < need) chunk.reserve(std::max(need, per_frame * size_t(config.chunk_frames)));
  }

  void skip(SkipReason r) {
    counts.add(r);
    if (warned.insert(r).second)
      logger("dense")->warn("skipping frame: {} (further ones are only counted)", to_string(r));
  }
};

DenseReconstructor::DenseReconstructor(DenseConfig config) {
  config.validate();
  impl_ = std::make_unique<Impl>(config);
}

DenseReconstructor::~DenseReconstructor() = default;

void DenseReconstructor::count_skipped(SkipReason reason) { impl_->skip(reason); }
void DenseReconstructor::add_load_time(double ms) { impl_->timing.load += ms; }

IntegrateResult DenseReconstructor::integrate(const SE3& T_world_cam, const cv::Mat& bgr, const cv::Mat& depth16,
                                              const PinholeCamera& camera, const std::optional<SE3>& T_world_depthcam) {
  Impl& m = *impl_;
  if (m.finished) throw std::logic_error("DenseReconstructor::integrate after finish()");
  IntegrateResult out;
  auto reject = [&](SkipReason r) {
    m.skip(r);
    out.reason = r;
    return out;
  };
  if (!T_world_cam.is_finite() || (T_world_depthcam && !T_world_depthcam->is_finite()))
    return reject(SkipReason::kBadPose);
  const SE3& T_world_depth = T_world_depthcam ? *T_world_depthcam : T_world_cam;
  std::optional<SE3> T_colourcam_depthcam;
  if (T_world_depthcam) T_colourcam_depthcam = T_world_cam.inverse() * *T_world_depthcam;
  const SE3* colour_from_depth = T_colourcam_depthcam ? &*T_colourcam_depthcam : nullptr;
  if (bgr.empty() || depth16.empty() || bgr.type() != CV_8UC3 || depth16.type() != CV_16UC1)
    return reject(SkipReason::kBadImage);
  if (bgr.cols != camera.width || bgr.rows != camera.height || depth16.cols != camera.width ||
      depth16.rows != camera.height)
    return reject(SkipReason::kWrongImageSize);

  Stopwatch sw;
  const RayTable& rays = m.rays_for(camera);
  BackprojectParams params;
  params.min_depth = m.config.min_depth;
  params.max_depth = m.config.max_depth;
  params.stride = m.config.stride;
  m.reserve_chunk(camera);
  out.points = backproject(bgr, depth16, rays, T_world_depth, params, m.chunk, colour_from_depth);
  m.timing.backproject += sw.ms();
  if (out.points == 0) return reject(SkipReason::kNoValidDepth);
  out.used = true;
  m.counts.add(SkipReason::kNone);
  if (++m.chunk_frames >= m.config.chunk_frames) m.flush_chunk();

  if (m.tsdf && (m.counts.used - 1) % m.config.tsdf.every == 0) {
    Stopwatch st;
    m.tsdf->integrate(bgr, depth16, rays, T_world_depth, m.config.min_depth, m.config.max_depth, colour_from_depth);
    ++m.counts.tsdf_frames;
    m.timing.tsdf += st.ms();
  }
  return out;
}

DenseResult DenseReconstructor::finish() {
  Impl& m = *impl_;
  if (m.finished) throw std::logic_error("DenseReconstructor::finish called twice");
  m.finished = true;
  m.flush_chunk();
  m.stop_filter_thread();
  DenseResult r;
  r.cloud = m.accumulator.finish();
  r.raw_points = m.accumulator.stats().raw_points;
  r.peak_buffered_points = m.accumulator.stats().peak_points;
  m.timing.filter = m.accumulator.stats().filter_ms;
  if (m.config.remove_outliers && !r.cloud.empty()) {
    Stopwatch sw;
    r.cloud = remove_statistical_outliers(r.cloud, m.config.outliers);
    m.timing.outliers = sw.ms();
  }
  if (m.tsdf) {
    Stopwatch sw;
    r.mesh = m.tsdf->extract_mesh();
    m.timing.mesh = sw.ms();
    r.tsdf_blocks = m.tsdf->block_count();
    r.tsdf_bytes = m.tsdf->memory_bytes();
    m.tsdf.reset();
  }
  r.counts = m.counts;
  m.timing.total = m.wall.ms();
  r.timing = m.timing;
  return r;
}

}  // namespace cslam
