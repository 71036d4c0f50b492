#pragma once
// One TSDF submap of the live dense map: a window of consecutive keyframes of one client fused
// into volumes held in the submap's own frame (its reference keyframe's camera frame). The
// submap's place in the world follows that keyframe's current pose, so a correction (loop
// closure, map fusion, bundle adjustment) moves it rigidly; only when its keyframes moved
// relative to each other does it need re-integrating from their images.
#include <cstdint>
#include <memory>
#include <vector>

#include "cloud/point_cloud.h"
#include "core/ids.h"
#include "dense/dense_config.h"
#include "dense/tsdf_volume.h"
#include "geometry/se3.h"

namespace cslam {

// Carries its client: client << 16 | index of the client's submaps.
using SubmapId = std::uint32_t;
inline SubmapId make_submap_id(ClientId client, std::uint32_t index) {
  return (SubmapId(client) << 16) | (index & 0xFFFF);
}
inline ClientId submap_client(SubmapId id) { return ClientId(id >> 16); }

// Decoded images of one keyframe, ready to integrate.
struct DenseImages {
  cv::Mat bgr;    // CV_8UC3
  cv::Mat depth;  // CV_16UC1, raw units of the camera's depth factor
};

struct LiveDenseConfig {
  TsdfConfig tsdf{0.02f, 0.08f, 64.0f,
                  4,     1,     1};  // the meshed volume: voxel, truncation, weight cap, block-search stride
  TsdfConfig nav{0.05f, 0.15f, 64.0f, 4, 1, 1};  // coarse volume kept for navigation maps
  double min_depth = 0.3, max_depth = 4.0;       // metres
  int keyframes_per_submap = 8;
  double submap_max_distance = 1.0;  // a keyframe farther than this from the submap's first one opens a new submap (m)
  double submap_max_angle_deg = 45.0;  // ... or turned further than this
  // A submap is re-integrated when one of its keyframes moved relative to it so that the surface
  // it saw moved by more than this (m): translation + rotation angle x the keyframe's median depth.
  double reintegrate_displacement = 0.01;
  double integration_delay_s = 1.0;     // a keyframe waits this long for local BA before it is integrated
  double mesh_interval_s = 3.0;         // an open submap is re-meshed at most this often
  std::size_t max_pending_images = 16;  // decoded images held for keyframes waiting to be integrated
  // Throws ConfigError naming the bad value.
  void validate() const;
};

// A submap as readers see it: immutable, shared with the map's published view.
struct DenseSubmapView {
  SubmapId id = 0;
  ClientId client = 0;
  int group = -1;
  std::uint64_t version = 0;       // geometry (integration, re-integration)
  std::uint64_t pose_version = 0;  // pose alone (corrections)
  SE3 T_world_submap;
  std::vector<KeyFrameId> keyframes;
  std::shared_ptr<const TriangleMesh> mesh;      // submap frame
  std::shared_ptr<const TsdfVolume> nav_volume;  // submap frame, coarse
  float voxel_size = 0;
  std::size_t mesh_bytes = 0, volume_bytes = 0;  // held by this submap (fine volume while open, nav volume)
};

class DenseSubmap {
 public:
  struct Member {
    KeyFrameId id;
    SE3 T_submap_kf;          // where its colour image was integrated, in the submap frame
    SE3 T_cam_depthcam;       // where its depth image was taken, from the colour image's pose
    double median_depth = 0;  // of its depth image (m): how far a rotation moves what it saw
  };

  DenseSubmap(SubmapId id, int group, int map, const SE3& T_world_submap, const LiveDenseConfig& config);

  SubmapId id() const { return id_; }
  int map() const { return map_; }
  int group() const { return group_; }
  bool open() const { return fine_ != nullptr; }
  const std::vector<Member>& members() const { return members_; }
  const SE3& T_world_submap() const { return T_world_submap_; }
  std::uint64_t version() const { return mesh_version_; }  // of the published mesh
  std::uint64_t pose_version() const { return pose_version_; }
  bool mesh_stale() const { return mesh_stale_; }
  // The first member: it decides when the window is full (distance and angle).
  const SE3& T_world_first() const { return T_world_first_; }

  // Fuses one keyframe at T_world_cam (the group frame; its depth image at T_world_cam *
  // T_cam_depthcam, colours looked up where depth points project in the colour image).
  void integrate(KeyFrameId id, const SE3& T_world_cam, const DenseImages& images, const RayTable& rays,
                 const SE3& T_cam_depthcam = SE3());
  // Moves the submap rigidly; bumps pose_version if it moved.
  void set_pose(const SE3& T_world_submap, int group);
  // Drops members culled by local mapping (their contribution stays until a re-integration).
  void forget(KeyFrameId id);
  // Rebuilds both volumes from the given members (their current poses in the group frame, the
  // first one the new reference), then meshes. Closed submaps drop the fine volume again.
  struct Reintegration {
    KeyFrameId id;
    SE3 T_world_cam;
    const DenseImages* images;  // null: lost from the store, left out
    const RayTable* rays;
    SE3 T_cam_depthcam;
  };
  void reintegrate(const std::vector<Reintegration>& members, int group);
  // Marching cubes over the fine volume (only while it exists).
  void remesh();
  // Meshes, then releases the fine volume: the window is complete.
  void close();

  DenseSubmapView view() const;

 private:
  const SubmapId id_;
  int group_;
  const int map_;
  const LiveDenseConfig& config_;
  SE3 T_world_submap_, T_world_first_;
  std::vector<Member> members_;
  std::unique_ptr<TsdfVolume> fine_;
  std::shared_ptr<TsdfVolume> nav_;
  std::shared_ptr<const TsdfVolume> nav_published_;
  std::shared_ptr<const TriangleMesh> mesh_;
  std::uint64_t version_ = 0, pose_version_ = 0;
  std::uint64_t mesh_version_ = 0;  // version_ when the published mesh was extracted
  bool mesh_stale_ = false;
};

}  // namespace cslam
