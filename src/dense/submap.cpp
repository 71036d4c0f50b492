#include "dense/submap.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace cslam {

namespace {

// Median of the valid depths (m) on a sparse grid of the image; 0 if none.
double median_depth(const cv::Mat& depth, double scale, double min_depth, double max_depth) {
  std::vector<float> z;
  z.reserve(std::size_t(depth.rows / 8 + 1) * std::size_t(depth.cols / 8 + 1));
  for (int v = 0; v < depth.rows; v += 8) {
    const std::uint16_t* row = depth.ptr<std::uint16_t>(v);
    for (int u = 0; u < depth.cols; u += 8) {
      const double d = row[u] * scale;
      if (row[u] != 0 && d >= min_depth && d <= max_depth) z.push_back(float(d));
    }
  }
  if (z.empty()) return 0;
  std::nth_element(z.begin(), z.begin() + std::ptrdiff_t(z.size() / 2), z.end());
  return z[z.size() / 2];
}

}  // namespace

void LiveDenseConfig::validate() const {
  auto check_tsdf = [](const TsdfConfig& c, const char* what) {
    if (!(c.voxel_size > 0) || !(c.truncation >= c.voxel_size) || !(c.max_weight >= 1) || c.stride < 1)
      throw ConfigError(std::string("dense map: ") + what +
                        " needs voxel > 0, truncation >= voxel, weight cap >= 1, stride >= 1");
  };
  check_tsdf(tsdf, "mesh volume");
  check_tsdf(nav, "navigation volume");
  if (!(min_depth > 0) || !(max_depth > min_depth)) throw ConfigError("dense map: need 0 < min_depth < max_depth");
  if (keyframes_per_submap < 1) throw ConfigError("dense map: keyframes_per_submap must be >= 1");
  if (!(submap_max_distance > 0) || !(submap_max_angle_deg > 0))
    throw ConfigError("dense map: submap_max_distance and submap_max_angle_deg must be positive");
  if (!(reintegrate_displacement > 0)) throw ConfigError("dense map: reintegrate_displacement must be positive");
  if (!(integration_delay_s >= 0) || !(mesh_interval_s >= 0)) throw ConfigError("dense map: delays must be >= 0");
  if (max_pending_images < 1) throw ConfigError("dense map: max_pending_images must be >= 1");
}

DenseSubmap::DenseSubmap(SubmapId id, int group, int map, const SE3& T_world_submap, const LiveDenseConfig& config)
    : id_(id),
      group_(group),
      map_(map),
      config_(config),
      T_world_submap_(T_world_submap),
      T_world_first_(T_world_submap),
      fine_(std::make_unique<TsdfVolume>(config.tsdf)),
      nav_(std::make_shared<TsdfVolume>(config.nav)) {}

void DenseSubmap::integrate(KeyFrameId id, const SE3& T_world_cam, const DenseImages& images, const RayTable& rays,
                            const SE3& T_cam_depthcam) {
  if (!fine_) throw std::logic_error("DenseSubmap::integrate on a closed submap");
  const SE3 T_submap_cam = T_world_submap_.inverse() * T_world_cam;
  const SE3 T_submap_depthcam = T_submap_cam * T_cam_depthcam;
  const bool moved = !(T_cam_depthcam.translation().isZero() && T_cam_depthcam.rotation().w() == 1.0);
  const SE3* T_colourcam_depthcam = moved ? &T_cam_depthcam : nullptr;
  fine_->integrate(images.bgr, images.depth, rays, T_submap_depthcam, config_.min_depth, config_.max_depth,
                   T_colourcam_depthcam);
  if (nav_.use_count() > 1) nav_ = std::make_shared<TsdfVolume>(*nav_);  // readers keep the published copy
  nav_->integrate(images.bgr, images.depth, rays, T_submap_depthcam, config_.min_depth, config_.max_depth,
                  T_colourcam_depthcam);
  if (members_.empty()) T_world_first_ = T_world_cam;
  const PinholeCamera& cam = rays.camera();
  members_.push_back({id, T_submap_cam, T_cam_depthcam,
                      median_depth(images.depth, cam.depth_scale_correction / cam.depth_factor, config_.min_depth,
                                   config_.max_depth)});
  ++version_;
  mesh_stale_ = true;
}

void DenseSubmap::set_pose(const SE3& T_world_submap, int group) {
  const SE3 d = T_world_submap_.inverse() * T_world_submap;
  const bool moved = d.translation().norm() > 1e-6 || std::abs(d.rotation().w()) < 1.0 - 1e-12 || group != group_;
  T_world_first_ = T_world_submap * (T_world_submap_.inverse() * T_world_first_);
  T_world_submap_ = T_world_submap;
  group_ = group;
  if (moved) ++pose_version_;
}

void DenseSubmap::forget(KeyFrameId id) {
  members_.erase(std::remove_if(members_.begin(), members_.end(), [&](const Member& m) { return m.id == id; }),
                 members_.end());
}

void DenseSubmap::reintegrate(const std::vector<Reintegration>& members, int group) {
  const bool was_open = open();
  members_.clear();
  if (!members.empty()) {
    T_world_submap_ = members.front().T_world_cam;
    T_world_first_ = members.front().T_world_cam;
  }
  group_ = group;
  fine_ = std::make_unique<TsdfVolume>(config_.tsdf);
  nav_ = std::make_shared<TsdfVolume>(config_.nav);
  for (const Reintegration& m : members)
    if (m.images) integrate(m.id, m.T_world_cam, *m.images, *m.rays, m.T_cam_depthcam);
  ++version_;
  ++pose_version_;
  remesh();
  if (!was_open) fine_.reset();
}

void DenseSubmap::remesh() {
  if (!fine_) return;
  mesh_ = std::make_shared<const TriangleMesh>(fine_->extract_mesh());
  nav_published_ = nav_;
  mesh_version_ = version_;
  mesh_stale_ = false;
}

void DenseSubmap::close() {
  if (mesh_stale_ || !mesh_) remesh();
  fine_.reset();
}

DenseSubmapView DenseSubmap::view() const {
  DenseSubmapView v;
  v.id = id_;
  v.client = submap_client(id_);
  v.group = group_;
  v.version = mesh_version_;
  v.pose_version = pose_version_;
  v.T_world_submap = T_world_submap_;
  for (const Member& m : members_) v.keyframes.push_back(m.id);
  v.mesh = mesh_;
  v.nav_volume = nav_published_;
  v.voxel_size = config_.tsdf.voxel_size;
  if (mesh_)
    v.mesh_bytes = mesh_->vertices.size() * (sizeof(Eigen::Vector3f) + sizeof(Rgb8)) +
                   mesh_->triangles.size() * sizeof(mesh_->triangles[0]);
  v.volume_bytes = (fine_ ? fine_->memory_bytes() : 0) + (nav_ ? nav_->memory_bytes() : 0);
  return v;
}

}  // namespace cslam
