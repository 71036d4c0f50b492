#pragma once
// Truncated signed distance volume in a voxel hash: blocks of 8^3 voxels allocated where
// surfaces are observed, stored in a hash map keyed by block coordinates. Each voxel keeps a
// weighted running average of the truncated SDF (in units of the truncation, [-1, 1]) and of
// the colour. extract_mesh() runs marching cubes over the blocks.
#include <array>
#include <cstdint>
#include <unordered_map>

#include <opencv2/core.hpp>

#include "cloud/point_cloud.h"
#include "dense/backproject.h"
#include "dense/dense_config.h"
#include "geometry/se3.h"

namespace cslam {

struct TsdfVoxel {
  float sdf = 1.0f;     // truncated signed distance / truncation: > 0 in front of the surface
  float weight = 0.0f;  // 0 = never observed
  std::uint8_t r = 0, g = 0, b = 0;
};

struct TsdfIntegrateStats {
  std::size_t blocks_touched = 0, blocks_allocated = 0;
};

class TsdfVolume {
 public:
  static constexpr int kBlockSide = 8;
  struct Block {
    std::array<TsdfVoxel, kBlockSide * kBlockSide * kBlockSide> voxels;
  };

  explicit TsdfVolume(TsdfConfig config);  // throws ConfigError on impossible values

  // Fuses one registered RGB-D frame (images of the ray table's camera size); T_world_cam places
  // the depth image, T_colourcam_depthcam (if the camera moved between the two captures) finds
  // each voxel's pixel in the colour image.
  TsdfIntegrateStats integrate(const cv::Mat& bgr, const cv::Mat& depth, const RayTable& rays, const SE3& T_world_cam,
                               double min_depth, double max_depth, const SE3* T_colourcam_depthcam = nullptr);

  // Marching cubes at sdf = 0 over observed voxels; vertices shared between cubes; colours
  // interpolated. Cubes straddling an observed/unobserved border or a +1/-1 jump (occlusion
  // edge, not a surface) make no triangles.
  TriangleMesh extract_mesh() const;

  std::size_t block_count() const { return blocks_.size(); }
  std::size_t memory_bytes() const { return blocks_.size() * (sizeof(Block) + 32); }
  const TsdfConfig& config() const { return config_; }
  // Voxel at global voxel coordinates, or nullptr if its block is not allocated.
  const TsdfVoxel* voxel(const Eigen::Vector3i& v) const;
  // Calls f(voxel_index, voxel) for every observed voxel (weight > 0) of every allocated block,
  // in no particular order. The voxel's centre is (voxel_index + 0.5) * voxel_size in the
  // volume's frame; its signed distance in metres is voxel.sdf * truncation.
  template <typename F>
  void for_each_observed_voxel(F&& f) const {
    for (const auto& [key, block] : blocks_) {
      const Eigen::Vector3i origin = block_origin(key);
      for (int z = 0; z < kBlockSide; ++z)
        for (int y = 0; y < kBlockSide; ++y)
          for (int x = 0; x < kBlockSide; ++x) {
            const TsdfVoxel& v = block.voxels[std::size_t((z * kBlockSide + y) * kBlockSide + x)];
            if (v.weight > 0) f(Eigen::Vector3i(origin.x() + x, origin.y() + y, origin.z() + z), v);
          }
    }
  }

 private:
  Block& block_at(std::uint64_t key);
  // Global voxel index of a block's first voxel.
  static Eigen::Vector3i block_origin(std::uint64_t key);

  TsdfConfig config_;
  std::unordered_map<std::uint64_t, Block> blocks_;
};

}  // namespace cslam
