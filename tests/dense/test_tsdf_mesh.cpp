// TsdfVolume::extract_mesh on surfaces with many vertices per block: each cube edge gives one
// vertex shared by the cubes around it, every triangle indexes existing vertices, and a mesh from
// a rough surface (more vertices than the edge table holds at first, so it grows) is as well
// formed as one from a plane. Two edges can put their vertices at the same place only at a voxel
// centre (a crossing exactly at a corner); an edge with two vertices would put them anywhere.
#include <cmath>
#include <random>
#include <set>
#include <tuple>

#include <gtest/gtest.h>

#include "common/small_camera.h"
#include "dense/backproject.h"
#include "dense/edge_vertex_table.h"
#include "dense/tsdf_volume.h"

using namespace cslam;

namespace {

TsdfVolume integrate(const cv::Mat& depth, float voxel) {
  const PinholeCamera cam = test::small_camera();
  TsdfConfig tc;
  tc.voxel_size = voxel;
  tc.truncation = 4 * voxel;
  tc.stride = 1;
  TsdfVolume volume(tc);
  volume.integrate(test::plane_colour(cam), depth, RayTable(cam), SE3(), 0.3, 4.0);
  return volume;
}

void expect_well_formed(const TriangleMesh& mesh, float voxel) {
  ASSERT_EQ(mesh.colors.size(), mesh.vertices.size());
  std::set<std::tuple<float, float, float>> places;
  auto at_voxel_centre = [voxel](const Eigen::Vector3f& v) {
    for (int k = 0; k < 3; ++k) {
      const float f = v[k] / voxel - 0.5f;
      if (std::abs(f - std::round(f)) > 1e-3f) return false;
    }
    return true;
  };
  int shared_places = 0;
  for (const Eigen::Vector3f& v : mesh.vertices)
    if (!places.emplace(v.x(), v.y(), v.z()).second) {
      EXPECT_TRUE(at_voxel_centre(v)) << "an edge got two vertices at " << v.transpose();
      ++shared_places;
    }
  EXPECT_LT(shared_places, int(mesh.vertices.size() / 20));
  std::vector<char> used(mesh.vertices.size(), 0);
  for (const auto& t : mesh.triangles) {
    for (std::uint32_t i : t) {
      ASSERT_LT(i, mesh.vertices.size());
      used[i] = 1;
    }
    EXPECT_TRUE(t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
  }
  for (char u : used) EXPECT_TRUE(u) << "a vertex no triangle uses";
}

}  // namespace

TEST(TsdfMesh, PlaneAndRoughSurfaceShareEveryEdgeVertex) {
  const PinholeCamera cam = test::small_camera();
  const TsdfVolume plane = integrate(test::plane_depth(cam, 1.0), 0.01f);
  const TriangleMesh flat = plane.extract_mesh();
  ASSERT_GT(flat.triangles.size(), 1000u);
  expect_well_formed(flat, 0.01f);

  // Depth noise of a few voxels at every pixel: the zero crossing folds inside every block.
  cv::Mat rough = test::plane_depth(cam, 0.8);
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> noise(-60, 60);  // +-1.2 cm at 5000 units per metre
  for (int v = 0; v < rough.rows; ++v)
    for (int u = 0; u < rough.cols; ++u) rough.at<std::uint16_t>(v, u) += std::uint16_t(noise(rng));
  const TsdfVolume folded = integrate(rough, 0.004f);
  const TriangleMesh mesh = folded.extract_mesh();
  // More vertices than 64 per block: the edge table (sized for 64 per block) had to grow.
  EXPECT_GT(mesh.vertices.size(), 64 * folded.block_count());
  expect_well_formed(mesh, 0.004f);
}

TEST(TsdfMesh, EdgeTableKeepsEveryVertexThroughGrowth) {
  // Far more keys than the table starts with (it grows five times), as edge keys look: 20 bits
  // per coordinate and an axis.
  EdgeVertexTable table(10);
  std::mt19937_64 rng(9);
  std::vector<std::uint64_t> keys;
  std::set<std::uint64_t> distinct;
  while (keys.size() < 40000) {
    const std::uint64_t k = (rng() & 0x0FFFFFFFFFFFFFFFull) | (std::uint64_t(rng() % 3) << 60);
    if (distinct.insert(k).second) keys.push_back(k);
  }
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const auto [vertex, inserted] = table.try_emplace(keys[i], std::uint32_t(i));
    EXPECT_TRUE(inserted);
    EXPECT_EQ(vertex, std::uint32_t(i));
  }
  EXPECT_EQ(table.size(), keys.size());
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const auto [vertex, inserted] = table.try_emplace(keys[i], 999999999u);
    ASSERT_FALSE(inserted) << i;
    ASSERT_EQ(vertex, std::uint32_t(i));
  }
  EXPECT_EQ(table.size(), keys.size());
}
