// Marching-cubes tables: every configuration produces triangles only on sign-changing edges,
// and a mesh of an analytic field is closed and consistently oriented (each directed edge used
// once, its reverse once), with normals pointing to increasing values.
#include <cmath>
#include <map>
#include <set>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "dense/marching_cubes.h"

using namespace cslam;

TEST(MarchingCubes, TrianglesUseExactlyTheCrossingEdges) {
  for (int config = 0; config < 256; ++config) {
    std::set<int> crossing, used;
    for (int e = 0; e < 12; ++e)
      if (((config >> mc_edge_corner(e, 0)) & 1) != ((config >> mc_edge_corner(e, 1)) & 1)) crossing.insert(e);
    for (const auto& t : mc_triangles(config))
      for (int e : t) used.insert(e);
    EXPECT_EQ(used, crossing) << "config " << config;
    EXPECT_LE(mc_triangles(config).size(), 12u);
  }
  EXPECT_TRUE(mc_triangles(0).empty());
  EXPECT_TRUE(mc_triangles(255).empty());
  EXPECT_EQ(mc_triangles(1).size(), 1u);
}

TEST(MarchingCubes, ClosedOrientedSurfaceOfAnalyticField) {
  // f = distance to two overlapping spheres minus radius, plus a wobble to hit many cases.
  const int n = 28;
  const double h = 1.0 / (n - 1);
  auto f = [&](int i, int j, int k) {
    const Eigen::Vector3d p(i * h, j * h, k * h);
    const double a = (p - Eigen::Vector3d(0.4, 0.45, 0.5)).norm() - 0.25;
    const double b = (p - Eigen::Vector3d(0.62, 0.55, 0.5)).norm() - 0.2;
    return std::min(a, b) + 0.03 * std::sin(37 * p.x()) * std::cos(29 * p.y()) * std::sin(23 * p.z());
  };
  std::map<std::tuple<int, int, int, int>, int> vid;  // (grid corner, axis) -> vertex id
  std::vector<Eigen::Vector3d> verts;
  std::vector<std::array<int, 3>> tris;
  std::set<int> configs_seen;
  for (int i = 0; i + 1 < n; ++i)
    for (int j = 0; j + 1 < n; ++j)
      for (int k = 0; k + 1 < n; ++k) {
        double v[8];
        int config = 0;
        for (int c = 0; c < 8; ++c) {
          v[c] = f(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
          if (v[c] < 0) config |= 1 << c;
        }
        configs_seen.insert(config);
        for (const auto& t : mc_triangles(config)) {
          std::array<int, 3> ids{};
          for (int q = 0; q < 3; ++q) {
            const int ca = mc_edge_corner(t[q], 0), cb = mc_edge_corner(t[q], 1);
            const auto key =
                std::make_tuple(i + (ca & 1), j + ((ca >> 1) & 1), k + ((ca >> 2) & 1), mc_edge_axis(t[q]));
            auto it = vid.find(key);
            if (it == vid.end()) {
              const double s = v[ca] / (v[ca] - v[cb]);
              Eigen::Vector3d p(std::get<0>(key) * h, std::get<1>(key) * h, std::get<2>(key) * h);
              p[mc_edge_axis(t[q])] += s * h;
              it = vid.emplace(key, int(verts.size())).first;
              verts.push_back(p);
            }
            ids[q] = it->second;
          }
          tris.push_back(ids);
        }
      }
  EXPECT_GT(configs_seen.size(), 60u);
  ASSERT_GT(tris.size(), 1000u);
  std::map<std::pair<int, int>, int> directed;
  for (const auto& t : tris)
    for (int q = 0; q < 3; ++q) ++directed[{t[q], t[(q + 1) % 3]}];
  int bad = 0;
  for (const auto& [e, count] : directed)
    if (count != 1 || directed.count({e.second, e.first}) == 0 || directed.at({e.second, e.first}) != 1) ++bad;
  EXPECT_EQ(bad, 0) << "open or inconsistently oriented edges";
  // Orientation: the normal points outwards (away from the first sphere's centre) near its far side.
  int outward = 0, checked = 0;
  for (const auto& t : tris) {
    const Eigen::Vector3d c = (verts[t[0]] + verts[t[1]] + verts[t[2]]) / 3;
    if (c.x() > 0.3) continue;
    const Eigen::Vector3d nrm = (verts[t[1]] - verts[t[0]]).cross(verts[t[2]] - verts[t[0]]);
    ++checked;
    if (nrm.dot(c - Eigen::Vector3d(0.4, 0.45, 0.5)) > 0) ++outward;
  }
  ASSERT_GT(checked, 50);
  EXPECT_GT(outward, checked * 95 / 100);
}
