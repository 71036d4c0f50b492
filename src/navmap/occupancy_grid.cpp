#include "navmap/occupancy_grid.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "core/error.h"
#include "navmap/voxel_walk.h"

namespace cslam {

namespace {

constexpr std::int64_t kBias = std::int64_t(1) << 30;

std::uint64_t cell_key(std::int64_t i, std::int64_t j) {
  return std::uint64_t(i + kBias) << 32 | std::uint64_t(j + kBias);
}
std::int64_t key_i(std::uint64_t k) { return std::int64_t(k >> 32) - kBias; }
std::int64_t key_j(std::uint64_t k) { return std::int64_t(k & 0xFFFFFFFFu) - kBias; }

struct Evidence {
  int occupied = 0, free = 0;  // band voxels: obstacle (signed distance <= 0) / free
  int tops = 0;                // upward-facing surface points in the band (a box or table top)
  bool floor = false;
  float low = 1e30f, high = -1e30f;  // heights of the obstacle evidence
  float free_low = 1e30f;            // lowest free band voxel
  void add_obstacle(double h, int& counter) {
    ++counter;
    low = std::min(low, float(h));
    high = std::max(high, float(h));
  }
  // A top seen at a grazing angle leaves few voxels behind it (the projective distance grows
  // past the truncation) but one zero crossing per voxel column: both count.
  bool obstacle(const NavMapConfig& c, double voxel) const {
    const int n = occupied + tops;
    if (n < c.min_occupied_voxels) return false;
    const double per_layer = (c.resolution / voxel) * (c.resolution / voxel);
    return double(high - low) + voxel >= c.min_obstacle_height || n >= c.min_obstacle_fill * per_layer;
  }
  // Free space seen only high in the band (above a box whose sides hide the rest) says nothing
  // about the band below it: the free voxels must reach down to band_min + min_obstacle_height.
  bool clear(const NavMapConfig& c) const {
    return floor || (free >= c.min_free_voxels && double(free_low) <= c.band_min + c.min_obstacle_height);
  }
};

// Plane coordinates of world points: cell indices along the grid's x and y.
struct PlaneIndexer {
  Eigen::Vector3d x, y;
  double inv_r;
  bool operator()(const Eigen::Vector3d& p, std::uint64_t& key) const {
    const double a = std::floor(x.dot(p) * inv_r), b = std::floor(y.dot(p) * inv_r);
    if (!(std::abs(a) < double(kBias - 1) && std::abs(b) < double(kBias - 1))) return false;
    key = cell_key(std::int64_t(a), std::int64_t(b));
    return true;
  }
};

std::unordered_map<std::uint64_t, Evidence> submap_evidence(const SubmapView& view, const PlaneIndexer& index,
                                                            const Eigen::Vector3d& up, double floor,
                                                            const NavMapConfig& c, GridStats& stats) {
  std::unordered_map<std::uint64_t, Evidence> ev;
  std::uint64_t key = 0;
  for_each_world_voxel(view, c.min_voxel_weight, [&](const Eigen::Vector3d& p, double d, const TsdfVoxel&) {
    const double h = up.dot(p) - floor;
    if (h < c.band_min || h > c.band_max) return;
    if (!index(p, key)) {
      ++stats.voxels_out_of_range;
      return;
    }
    ++stats.band_voxels;
    Evidence& e = ev[key];
    if (d > 0) {
      ++e.free;
      e.free_low = std::min(e.free_low, float(h));
    } else
      e.add_obstacle(h, e.occupied);
  });
  for_each_upward_crossing(view, up, c.min_voxel_weight, [&](const Eigen::Vector3d& p) {
    const double h = up.dot(p) - floor;
    const bool on_floor = std::abs(h) <= c.floor_tolerance;
    if (!on_floor && (h < c.band_min || h > c.band_max)) return;
    if (!index(p, key)) {
      ++stats.voxels_out_of_range;
      return;
    }
    Evidence& e = ev[key];
    if (on_floor) {
      ++stats.floor_samples;
      e.floor = true;
    } else {
      e.add_obstacle(h, e.tops);
    }
  });
  return ev;
}

}  // namespace

Eigen::Matrix3d grid_rotation(const Eigen::Vector3d& up_in) {
  const Eigen::Vector3d up = up_in.normalized();
  Eigen::Vector3d x = Eigen::Vector3d::UnitZ() - up.z() * up;
  if (x.norm() < 0.2) x = Eigen::Vector3d::UnitX() - up.x() * up;
  x.normalize();
  Eigen::Matrix3d R;
  R.col(0) = x;
  R.col(1) = up.cross(x);
  R.col(2) = up;
  return R;
}

GridResult build_occupancy_grid(const SubmapViews& views, const Eigen::Vector3d& up_in, double floor,
                                const NavMapConfig& c) {
  c.validate();
  if (!up_in.allFinite() || up_in.norm() < 1e-9) throw ConfigError("navmap: up must be a finite non-zero vector");
  if (!std::isfinite(floor)) throw ConfigError("navmap: floor height must be finite");
  const Eigen::Vector3d up = up_in.normalized();
  const Eigen::Matrix3d R = grid_rotation(up);
  const PlaneIndexer index{R.col(0), R.col(1), 1.0 / c.resolution};

  GridResult out;
  std::unordered_map<std::uint64_t, float> log_odds;
  for (const SubmapView& v : views) {
    if (!usable(v)) {
      ++out.stats.submaps_skipped;
      continue;
    }
    ++out.stats.submaps_used;
    const double voxel = v.volume->config().voxel_size;
    for (const auto& [key, e] : submap_evidence(v, index, up, floor, c, out.stats)) {
      if (e.obstacle(c, voxel))
        log_odds[key] += c.log_odds_occupied;
      else if (e.clear(c))
        log_odds[key] += c.log_odds_free;
    }
  }
  if (log_odds.empty()) return out;

  std::int64_t i0 = key_i(log_odds.begin()->first), i1 = i0, j0 = key_j(log_odds.begin()->first), j1 = j0;
  for (const auto& kv : log_odds) {
    i0 = std::min(i0, key_i(kv.first)), i1 = std::max(i1, key_i(kv.first));
    j0 = std::min(j0, key_j(kv.first)), j1 = std::max(j1, key_j(kv.first));
  }
  const std::int64_t W = i1 - i0 + 1, H = j1 - j0 + 1;
  if (double(W) * double(H) > double(c.max_cells)) {
    out.error = "occupancy grid of " + std::to_string(W) + " x " + std::to_string(H) + " cells exceeds the budget of " +
                std::to_string(c.max_cells) + " cells";
    return out;
  }
  OccupancyGrid2D& g = out.grid;
  g.width = int(W);
  g.height = int(H);
  g.resolution = c.resolution;
  const Eigen::Vector3d origin =
      double(i0) * c.resolution * R.col(0) + double(j0) * c.resolution * R.col(1) + floor * up;
  g.T_world_grid = SE3(R, origin);
  g.cells.assign(std::size_t(W * H), OccupancyGrid2D::kUnknown);
  for (const auto& [key, L] : log_odds) {
    std::int8_t& cell = g.cells[std::size_t((key_j(key) - j0) * W + (key_i(key) - i0))];
    cell = L > 0 ? OccupancyGrid2D::kOccupied : L < 0 ? OccupancyGrid2D::kFree : OccupancyGrid2D::kUnknown;
  }
  for (std::int8_t v : g.cells) {
    if (v == OccupancyGrid2D::kOccupied)
      ++out.stats.occupied;
    else if (v == OccupancyGrid2D::kFree)
      ++out.stats.free;
    else
      ++out.stats.unknown;
  }
  return out;
}

}  // namespace cslam
