#include "navmap/nav_maps.h"

#include "core/stopwatch.h"

namespace cslam {

NavMaps build_nav_maps(const SubmapViews& views, const std::vector<SE3>& T_world_cams, const NavMapConfig& config) {
  config.validate();
  const Stopwatch total;
  NavMaps out;
  Stopwatch sw;
  if (config.up) {
    out.up = config.up->normalized();
  } else {
    const UpEstimate up = estimate_up(T_world_cams, config.default_up);
    out.up = up.up;
    out.up_estimated = up.from_cameras;
    out.stats.cameras_used = up.cameras_used;
    out.stats.cameras_skipped = up.cameras_skipped;
  }
  if (config.floor_height) {
    out.floor = *config.floor_height;
    out.floor_rule = "given";
  } else {
    const FloorEstimate f = estimate_floor(views, out.up, config, T_world_cams);
    out.floor = f.height;
    out.floor_estimated = f.found;
    out.floor_rule = f.rule;
    out.stats.floor_samples = f.samples;
    if (!f.found) {
      for (const SubmapView& v : views) (usable(v) ? out.stats.submaps_used : out.stats.submaps_skipped) += 1;
      out.grid_error = out.octomap_error = "no observed surface";
      out.stats.up_floor_ms = out.stats.total_ms = total.ms();
      return out;
    }
  }
  out.stats.up_floor_ms = sw.ms();

  sw.reset();
  GridResult grid = build_occupancy_grid(views, out.up, out.floor, config);
  out.grid = std::move(grid.grid);
  out.grid_error = std::move(grid.error);
  out.stats.cells_occupied = grid.stats.occupied;
  out.stats.cells_free = grid.stats.free;
  out.stats.cells_unknown = grid.stats.unknown;
  out.stats.submaps_used = grid.stats.submaps_used;
  out.stats.submaps_skipped = grid.stats.submaps_skipped;
  out.stats.grid_ms = sw.ms();

  if (config.octomap) {
    sw.reset();
    OctomapResult oct = build_octomap(views, config);
    out.octomap_bt = std::move(oct.bt);
    out.octomap_error = std::move(oct.error);
    out.stats.octree_nodes = oct.nodes;
    out.stats.octree_occupied_leaves = oct.occupied_leaves;
    out.stats.octree_free_leaves = oct.free_leaves;
    out.stats.octomap_ms = sw.ms();
  }
  out.stats.total_ms = total.ms();
  return out;
}

}  // namespace cslam
