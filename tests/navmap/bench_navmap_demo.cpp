// Times build_nav_maps on a demo-sized dense map: the "demo" preset's room and 3 robots x 300
// frames, every 5th frame integrated at 320x240 into 1 cm TSDF submaps of 10 frames. Prints;
// asserts nothing. Usage: bench_navmap_demo [voxel_m] [runs]
#include <cstdio>
#include <cstdlib>

#include "core/stopwatch.h"
#include "navmap/nav_maps.h"
#include "synthetic_dense_map.h"

using namespace cslam;

int main(int argc, char** argv) {
  test::DenseFixtureOptions o;
  o.preset = "demo";
  o.robots = 3;
  o.frames = 300;
  o.loop = true;
  o.width = 320;
  o.height = 240;
  o.every = 5;
  o.window = 10;
  o.voxel = argc > 1 ? float(std::atof(argv[1])) : 0.01f;
  o.truncation = 4 * o.voxel;
  const int runs = argc > 2 ? std::atoi(argv[2]) : 3;
  const Stopwatch sw;
  const test::DenseFixture f = test::make_dense_fixture(o);
  std::size_t blocks = 0, bytes = 0;
  for (const auto& v : f.volumes) blocks += v->block_count(), bytes += v->memory_bytes();
  std::printf("dense map: %zu submaps, %zu frames, voxel %.3f m, %zu blocks (%.1f MB), made in %.1f s\n",
              f.views.size(), f.frames_integrated, double(o.voxel), blocks, double(bytes) / 1e6, sw.ms() / 1000);
  for (int r = 0; r < runs; ++r) {
    const NavMaps m = build_nav_maps(f.views, f.T_world_cams, NavMapConfig{});
    std::printf(
        "run %d: total %.0f ms (up+floor %.0f, grid %.0f, octomap %.0f); grid %d x %d: %zu occupied %zu free %zu "
        "unknown; octree %zu nodes, .bt %zu bytes; floor %s\n",
        r + 1, m.stats.total_ms, m.stats.up_floor_ms, m.stats.grid_ms, m.stats.octomap_ms, m.grid.width, m.grid.height,
        m.stats.cells_occupied, m.stats.cells_free, m.stats.cells_unknown, m.stats.octree_nodes, m.octomap_bt.size(),
        m.floor_rule.c_str());
  }
  return 0;
}
