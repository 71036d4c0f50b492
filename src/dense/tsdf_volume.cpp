#include "dense/tsdf_volume.h"

#include <algorithm>
#include <cmath>
#include <thread>
#include <unordered_set>
#include <vector>

#include "core/error.h"
#include "dense/edge_vertex_table.h"
#include "dense/marching_cubes.h"

namespace cslam {

namespace {

constexpr int kB = TsdfVolume::kBlockSide;
constexpr std::int64_t kKeyBias = 1 << 20;

std::uint64_t block_key(int x, int y, int z) {
  return (std::uint64_t(x + kKeyBias) & 0x1FFFFF) | ((std::uint64_t(y + kKeyBias) & 0x1FFFFF) << 21) |
         ((std::uint64_t(z + kKeyBias) & 0x1FFFFF) << 42);
}
Eigen::Vector3i key_to_block(std::uint64_t k) {
  return {int(std::int64_t(k & 0x1FFFFF) - kKeyBias), int(std::int64_t((k >> 21) & 0x1FFFFF) - kKeyBias),
          int(std::int64_t((k >> 42) & 0x1FFFFF) - kKeyBias)};
}
int floor_div(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }
int local_index(int x, int y, int z) { return (z * kB + y) * kB + x; }

}  // namespace

TsdfVolume::TsdfVolume(TsdfConfig config) : config_(config) {
  if (!(config_.voxel_size > 0)) throw ConfigError("tsdf: voxel_size must be positive");
  if (!(config_.truncation >= config_.voxel_size)) throw ConfigError("tsdf: truncation must be at least one voxel");
  if (!(config_.max_weight >= 1)) throw ConfigError("tsdf: max_weight must be >= 1");
  if (config_.stride < 1 || config_.every < 1 || config_.threads < 1)
    throw ConfigError("tsdf: stride, every and threads must be >= 1");
}

Eigen::Vector3i TsdfVolume::block_origin(std::uint64_t key) { return key_to_block(key) * kB; }

TsdfVolume::Block& TsdfVolume::block_at(std::uint64_t key) { return blocks_[key]; }

const TsdfVoxel* TsdfVolume::voxel(const Eigen::Vector3i& v) const {
  const int bx = floor_div(v.x(), kB), by = floor_div(v.y(), kB), bz = floor_div(v.z(), kB);
  const auto it = blocks_.find(block_key(bx, by, bz));
  if (it == blocks_.end()) return nullptr;
  return &it->second.voxels[size_t(local_index(v.x() - bx * kB, v.y() - by * kB, v.z() - bz * kB))];
}

TsdfIntegrateStats TsdfVolume::integrate(const cv::Mat& bgr, const cv::Mat& depth, const RayTable& rays,
                                         const SE3& T_world_cam, double min_depth, double max_depth,
                                         const SE3* T_colourcam_depthcam) {
  const PinholeCamera& cam = rays.camera();
  const float voxel = config_.voxel_size, trunc = config_.truncation;
  const float block_size = voxel * kB, inv_block = 1.0f / block_size;
  const float scale = float(cam.depth_scale_correction / cam.depth_factor);
  const float zmin = float(min_depth), zmax = float(max_depth);
  const Eigen::Matrix3f R = T_world_cam.R().cast<float>();
  const Eigen::Vector3f t = T_world_cam.translation().cast<float>();

  // 1. Blocks within the truncation band around every (strided) measured point.
  std::unordered_set<std::uint64_t> touched;
  touched.reserve(8192);
  for (int v = 0; v < cam.height; v += config_.stride) {
    const std::uint16_t* drow = depth.ptr<std::uint16_t>(v);
    for (int u = 0; u < cam.width; u += config_.stride) {
      const float z = drow[u] * scale;
      if (drow[u] == 0 || z < zmin || z > zmax) continue;
      const float* r = rays.ray(u, v);
      const Eigen::Vector3f dir = R * Eigen::Vector3f(r[0], r[1], 1.0f);
      const float len = 2 * trunc * dir.norm();
      const int steps = int(std::ceil(len / (0.5f * block_size))) + 1;
      for (int s = 0; s <= steps; ++s) {
        const float zz = z - trunc + 2 * trunc * float(s) / float(steps);
        const Eigen::Vector3f p = (dir * zz + t) * inv_block;
        touched.insert(block_key(int(std::floor(p.x())), int(std::floor(p.y())), int(std::floor(p.z()))));
      }
    }
  }
  TsdfIntegrateStats stats;
  stats.blocks_touched = touched.size();
  std::vector<std::pair<Eigen::Vector3i, Block*>> work;
  work.reserve(touched.size());
  const size_t before = blocks_.size();
  for (std::uint64_t k : touched) work.emplace_back(key_to_block(k), &block_at(k));  // references stay valid on rehash
  stats.blocks_allocated = blocks_.size() - before;

  // 2. Project every voxel of those blocks into the depth image and update it.
  const Eigen::Matrix3f Rt = R.transpose();
  const PixelProjector project(rays);
  const RigidF colour_from_depth(T_colourcam_depthcam);
  const float max_w = config_.max_weight, inv_trunc = 1.0f / trunc;
  auto update = [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const Eigen::Vector3i& bc = work[i].first;
      Block& block = *work[i].second;
      // Camera-frame centre of voxel (x, y, z) = base + x * ax + y * ay + z * az.
      const Eigen::Vector3f origin = bc.cast<float>() * block_size + Eigen::Vector3f::Constant(0.5f * voxel);
      const Eigen::Vector3f base = Rt * (origin - t);
      const Eigen::Vector3f ax = Rt.col(0) * voxel, ay = Rt.col(1) * voxel, az = Rt.col(2) * voxel;
      for (int z = 0; z < kB; ++z)
        for (int y = 0; y < kB; ++y) {
          const Eigen::Vector3f row = base + float(y) * ay + float(z) * az;
          for (int x = 0; x < kB; ++x) {
            const Eigen::Vector3f pc = row + float(x) * ax;
            int u, v;
            if (!project(pc, u, v)) continue;
            const std::uint16_t raw = depth.at<std::uint16_t>(v, u);
            const float d = raw * scale;
            if (raw == 0 || d < zmin || d > zmax) continue;
            const float sdf = d - pc.z();
            if (sdf < -trunc) continue;
            const float tsdf = std::min(1.0f, sdf * inv_trunc);
            TsdfVoxel& vx = block.voxels[size_t(local_index(x, y, z))];
            const float w = vx.weight, nw = w + 1.0f, inv = 1.0f / nw;
            vx.sdf = (vx.sdf * w + tsdf) * inv;
            int uc = u, vc = v;
            if (T_colourcam_depthcam && !project(colour_from_depth * pc, uc, vc)) uc = u, vc = v;
            const cv::Vec3b& c = bgr.at<cv::Vec3b>(vc, uc);
            vx.r = std::uint8_t((vx.r * w + c[2]) * inv + 0.5f);
            vx.g = std::uint8_t((vx.g * w + c[1]) * inv + 0.5f);
            vx.b = std::uint8_t((vx.b * w + c[0]) * inv + 0.5f);
            vx.weight = std::min(nw, max_w);
          }
        }
    }
  };
  const int threads = std::max(1, std::min<int>(config_.threads, int(work.size() / 64) + 1));
  std::vector<std::thread> pool;
  for (int k = 1; k < threads; ++k)
    pool.emplace_back(update, work.size() * k / threads, work.size() * (k + 1) / threads);
  update(0, work.size() / threads);
  for (auto& th : pool) th.join();
  return stats;
}

TriangleMesh TsdfVolume::extract_mesh() const {
  TriangleMesh mesh;
  // Vertex per (global voxel of the edge's first corner, axis): shared by the four cubes around the edge.
  EdgeVertexTable vertex_of_edge(blocks_.size() * 64);
  auto edge_key = [](const Eigen::Vector3i& g, int axis) {
    return (std::uint64_t(g.x() + (1 << 19)) & 0xFFFFF) | ((std::uint64_t(g.y() + (1 << 19)) & 0xFFFFF) << 20) |
           ((std::uint64_t(g.z() + (1 << 19)) & 0xFFFFF) << 40) | (std::uint64_t(axis) << 60);
  };
  const float voxel = config_.voxel_size;
  for (const auto& [key, block] : blocks_) {
    const Eigen::Vector3i bc = key_to_block(key);
    // The block and its +x/+y/+z neighbours hold every corner a cube of this block needs.
    std::array<const Block*, 8> nb{};
    for (int n = 0; n < 8; ++n) {
      const auto it = blocks_.find(block_key(bc.x() + (n & 1), bc.y() + ((n >> 1) & 1), bc.z() + ((n >> 2) & 1)));
      nb[size_t(n)] = it == blocks_.end() ? nullptr : &it->second;
    }
    auto corner_voxel = [&](int x, int y, int z) -> const TsdfVoxel* {
      const int n = (x >= kB ? 1 : 0) | (y >= kB ? 2 : 0) | (z >= kB ? 4 : 0);
      const Block* b = nb[size_t(n)];
      if (!b) return nullptr;
      return &b->voxels[size_t(local_index(x % kB, y % kB, z % kB))];
    };
    for (int z = 0; z < kB; ++z)
      for (int y = 0; y < kB; ++y)
        for (int x = 0; x < kB; ++x) {
          std::array<const TsdfVoxel*, 8> c{};
          int config = 0;
          float lo = 2, hi = -2;
          bool ok = true;
          const TsdfVoxel& first = block.voxels[size_t(local_index(x, y, z))];
          if (first.weight <= 0) continue;
          const bool inner = x + 1 < kB && y + 1 < kB && z + 1 < kB;
          for (int i = 0; i < 8 && ok; ++i) {
            const int cx = x + (i & 1), cy = y + ((i >> 1) & 1), cz = z + ((i >> 2) & 1);
            c[size_t(i)] = inner ? &block.voxels[size_t(local_index(cx, cy, cz))] : corner_voxel(cx, cy, cz);
            ok = c[size_t(i)] && c[size_t(i)]->weight > 0;
            if (!ok) break;
            if (c[size_t(i)]->sdf < 0) config |= 1 << i;
            lo = std::min(lo, c[size_t(i)]->sdf);
            hi = std::max(hi, c[size_t(i)]->sdf);
          }
          if (!ok || config == 0 || config == 255 || hi - lo > 1.0f) continue;
          const Eigen::Vector3i g = bc * kB + Eigen::Vector3i(x, y, z);
          for (const McTriangle& tri : mc_triangles(config)) {
            std::array<std::uint32_t, 3> idx{};
            for (int k = 0; k < 3; ++k) {
              const int e = tri[size_t(k)];
              const int ca = mc_edge_corner(e, 0), cb = mc_edge_corner(e, 1), axis = mc_edge_axis(e);
              const Eigen::Vector3i ga = g + Eigen::Vector3i(ca & 1, (ca >> 1) & 1, (ca >> 2) & 1);
              const auto [vertex, inserted] =
                  vertex_of_edge.try_emplace(edge_key(ga, axis), std::uint32_t(mesh.vertices.size()));
              if (inserted) {
                const TsdfVoxel& a = *c[size_t(ca)];
                const TsdfVoxel& b = *c[size_t(cb)];
                const float s = a.sdf / (a.sdf - b.sdf);
                Eigen::Vector3f p = (ga.cast<float>() + Eigen::Vector3f::Constant(0.5f)) * voxel;
                p[axis] += s * voxel;
                mesh.vertices.push_back(p);
                auto mix = [s](std::uint8_t u, std::uint8_t w) {
                  return std::uint8_t(u + s * (float(w) - float(u)) + 0.5f);
                };
                mesh.colors.push_back({mix(a.r, b.r), mix(a.g, b.g), mix(a.b, b.b)});
              }
              idx[size_t(k)] = vertex;
            }
            if (idx[0] != idx[1] && idx[1] != idx[2] && idx[0] != idx[2]) mesh.triangles.push_back(idx);
          }
        }
  }
  return mesh;
}

}  // namespace cslam
