#include "dense/mesh_lod.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

namespace cslam {

namespace {

std::uint64_t cell_key(const Eigen::Vector3f& p, float inv_cell) {
  const auto c = [&](float x) { return std::uint64_t(std::int64_t(std::floor(x * inv_cell)) + (1 << 20)) & 0x1FFFFF; };
  return c(p.x()) | (c(p.y()) << 21) | (c(p.z()) << 42);
}

struct Accumulator {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Vector3d colour = Eigen::Vector3d::Zero();
  int count = 0;
  std::uint32_t index = 0;
  void add(const Eigen::Vector3f& p, const Rgb8* c) {
    sum += p.cast<double>();
    if (c) colour += Eigen::Vector3d((*c)[0], (*c)[1], (*c)[2]);
    ++count;
  }
  Rgb8 mean_colour() const {
    const Eigen::Vector3d m = colour / std::max(1, count);
    return {std::uint8_t(m.x() + 0.5), std::uint8_t(m.y() + 0.5), std::uint8_t(m.z() + 0.5)};
  }
};

}  // namespace

TriangleMesh simplify_by_clustering(const TriangleMesh& mesh, float cell) {
  const float inv = 1.0f / cell;
  const bool coloured = mesh.colors.size() == mesh.vertices.size();
  std::unordered_map<std::uint64_t, Accumulator> cells;
  std::vector<std::uint32_t> remap(mesh.vertices.size());
  std::vector<const Accumulator*> order;
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    auto [it, fresh] = cells.try_emplace(cell_key(mesh.vertices[i], inv));
    if (fresh) {
      it->second.index = std::uint32_t(order.size());
      order.push_back(&it->second);
    }
    it->second.add(mesh.vertices[i], coloured ? &mesh.colors[i] : nullptr);
    remap[i] = it->second.index;
  }
  TriangleMesh out;
  out.vertices.reserve(order.size());
  for (const Accumulator* a : order) {
    out.vertices.push_back((a->sum / a->count).cast<float>());
    if (coloured) out.colors.push_back(a->mean_colour());
  }
  std::unordered_set<std::uint64_t> seen;
  for (const auto& t : mesh.triangles) {
    std::array<std::uint32_t, 3> n{remap[t[0]], remap[t[1]], remap[t[2]]};
    if (n[0] == n[1] || n[1] == n[2] || n[0] == n[2]) continue;
    // The same triangle once (in any rotation of its vertex order; orientation kept).
    const int first = int(std::min_element(n.begin(), n.end()) - n.begin());
    std::rotate(n.begin(), n.begin() + first, n.end());
    const std::uint64_t key = (std::uint64_t(n[0]) << 42) ^ (std::uint64_t(n[1]) << 21) ^ n[2];
    if (seen.insert(key).second) out.triangles.push_back(n);
  }
  return out;
}

TriangleMesh merge_meshes(const std::vector<PlacedMesh>& meshes) {
  TriangleMesh out;
  std::size_t nv = 0, nt = 0;
  for (const auto& m : meshes) nv += m.mesh->vertices.size(), nt += m.mesh->triangles.size();
  out.vertices.reserve(nv);
  out.colors.reserve(nv);
  out.triangles.reserve(nt);
  for (const auto& m : meshes) {
    const std::uint32_t base = std::uint32_t(out.vertices.size());
    const Eigen::Matrix3f R = m.T_world_mesh.R().cast<float>();
    const Eigen::Vector3f t = m.T_world_mesh.translation().cast<float>();
    for (const auto& v : m.mesh->vertices) out.vertices.push_back(R * v + t);
    if (m.mesh->colors.size() == m.mesh->vertices.size())
      out.colors.insert(out.colors.end(), m.mesh->colors.begin(), m.mesh->colors.end());
    else
      out.colors.resize(out.vertices.size(), Rgb8{200, 200, 200});
    for (const auto& tri : m.mesh->triangles) out.triangles.push_back({tri[0] + base, tri[1] + base, tri[2] + base});
  }
  return out;
}

ColoredCloud mesh_vertices_cloud(const std::vector<PlacedMesh>& meshes, float voxel) {
  const float inv = 1.0f / voxel;
  std::unordered_map<std::uint64_t, Accumulator> cells;
  std::vector<const Accumulator*> order;
  for (const auto& m : meshes) {
    const Eigen::Matrix3f R = m.T_world_mesh.R().cast<float>();
    const Eigen::Vector3f t = m.T_world_mesh.translation().cast<float>();
    const bool coloured = m.mesh->colors.size() == m.mesh->vertices.size();
    for (std::size_t i = 0; i < m.mesh->vertices.size(); ++i) {
      const Eigen::Vector3f p = R * m.mesh->vertices[i] + t;
      auto [it, fresh] = cells.try_emplace(cell_key(p, inv));
      if (fresh) order.push_back(&it->second);
      it->second.add(p, coloured ? &m.mesh->colors[i] : nullptr);
    }
  }
  ColoredCloud cloud;
  cloud.reserve(order.size());
  for (const Accumulator* a : order) {
    cloud.points.push_back((a->sum / a->count).cast<float>());
    cloud.colors.push_back(a->mean_colour());
  }
  return cloud;
}

}  // namespace cslam
