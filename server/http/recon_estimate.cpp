// The memory estimate of a reconstruction request (recon_jobs.h, estimate_recon_memory).
#include <algorithm>
#include <cmath>
#include <unordered_set>

#include "core/error.h"
#include "dense/tsdf_volume.h"
#include "io/tum_dataset.h"
#include "server/http/recon_jobs.h"

namespace cslam::http {

namespace {

// The depth image nearest to `t` (within 0.1 s), or end.
std::vector<TimedFile>::const_iterator nearest_depth(const std::vector<TimedFile>& depth, double t) {
  auto it =
      std::lower_bound(depth.begin(), depth.end(), t, [](const TimedFile& f, double x) { return f.timestamp < x; });
  if (it == depth.end())
    it = std::prev(it);
  else if (it != depth.begin() && t - std::prev(it)->timestamp < it->timestamp - t)
    it = std::prev(it);
  return std::abs(it->timestamp - t) > 0.1 ? depth.end() : it;
}

// Back-projects about 80 columns of the depth image `d` seen from `p` into cells of kCell.
void add_cells(const cv::Mat& d, const PinholeCamera& cam, const StampedPose& p, const DenseConfig& config,
               std::unordered_set<std::uint64_t>& cells) {
  constexpr double kCell = 0.10;
  const int px = std::max(1, cam.width / 80);
  const auto cell = [](double x) { return std::uint64_t(std::int64_t(std::floor(x / kCell)) & 0x1FFFFF); };
  for (int v = px / 2; v < d.rows; v += px)
    for (int u = px / 2; u < d.cols; u += px) {
      const double z = cam.depth_from_raw(d.at<std::uint16_t>(v, u));
      if (z < config.min_depth || z > config.max_depth) continue;
      const Eigen::Vector3d w = p.T_world_cam * cam.unproject(u, v, z);
      cells.insert(cell(w.x()) << 42 | cell(w.y()) << 21 | cell(w.z()));
    }
}

// The depth files of a source's dataset (empty if it cannot be read).
std::vector<TimedFile> depth_files(const DatasetPoses& s) {
  try {
    return open_tum_dataset(s.dataset_dir).depth;
  } catch (const std::exception&) {
    return {};
  }
}

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
    const std::vector<TimedFile> depth = depth_files(s);
    if (depth.empty()) continue;
    for (const StampedPose& p : s.poses) {
      if (k++ % step != 0 || !p.T_world_cam.is_finite()) continue;
      const auto it = nearest_depth(depth, p.timestamp);
      if (it == depth.end()) continue;
      // Read as the reconstruction reads it (load_rgbd); an unreadable image is left out here too.
      cv::Mat d;
      try {
        d = load_depth_image(it->path);
      } catch (const InputError&) {
        continue;
      }
      if (d.cols != s.camera.width || d.rows != s.camera.height) continue;
      ++read;
      add_cells(d, s.camera, p, config, cells);
    }
  }
  if (read == 0) return std::nullopt;
  return double(cells.size()) * kCell * kCell;
}

// The TSDF blocks over the surface and the mesh's triangles (48 bytes each, measured).
void add_mesh_estimate(const DenseConfig& config, ReconEstimate& e) {
  constexpr double kTriangleBytes = 48;
  const double vs = config.tsdf.voxel_size, block = TsdfVolume::kBlockSide * vs;
  const double band = 1 + 2 * config.tsdf.truncation / block;
  e.tsdf = e.surface_m2 / (block * block) * band * (double(sizeof(TsdfVolume::Block)) + 64);
  const double triangles = 2 * e.surface_m2 / (vs * vs);
  e.mesh = triangles * kTriangleBytes;
  e.ply += triangles * (13 + 0.5 * 15);
}

}  // namespace

// The parts of a request's memory. Constants measured with cslam-recon (--threads 1, as the
// server runs) on the synthetic 2 x 60-frame 320x240 scene (docs/security.md, "Reconstruction
// jobs"): about 100 bytes per back-projected point held in a chunk, 120 per filtered cloud point,
// 48 per mesh triangle, a TSDF block (8^3 voxels) over every block_side^2 of surface. The
// estimate came out 1.5-2x above the measured growth at every setting tried.
ReconEstimate estimate_recon_memory(const std::vector<DatasetPoses>& sources, const DenseConfig& config) {
  constexpr double kChunkPointBytes = 100, kCloudPointBytes = 120;
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
  e.chunk_points =
      std::min<double>(std::max(1, config.chunk_frames), double(e.frames)) * e.points_per_frame * kChunkPointBytes;
  e.cloud = cloud_points * kCloudPointBytes;
  e.ply = cloud_points * 15;  // binary: xyz float, rgb
  if (config.build_mesh) add_mesh_estimate(config, e);
  return e;
}

}  // namespace cslam::http
