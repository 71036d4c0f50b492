#include "dense/voxel_accumulator.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "cloud/filters.h"
#include "core/stopwatch.h"

namespace cslam {

namespace {
std::uint64_t voxel_key(const Eigen::Vector3f& p, float inv) {
  constexpr std::int64_t kBias = std::int64_t(1) << 20;
  auto c = [&](float v) { return std::uint64_t(std::int64_t(std::floor(v * inv)) + kBias) & 0x1FFFFF; };
  return c(p.x()) | (c(p.y()) << 21) | (c(p.z()) << 42);
}
}  // namespace

VoxelAccumulator::VoxelAccumulator(double voxel_size) : voxel_(float(voxel_size)) {
  if (!(voxel_size > 0)) throw std::invalid_argument("VoxelAccumulator: voxel size must be positive");
}

ColoredCloud VoxelAccumulator::filter_chunk(const ColoredCloud& chunk) const { return voxel_filter(chunk, voxel_); }

void VoxelAccumulator::merge(const ColoredCloud& filtered, std::size_t raw_points, double filter_ms) {
  if (filtered.empty()) return;
  Stopwatch sw;
  ++stats_.chunks;
  stats_.raw_points += raw_points;
  if (!filtered.has_colors()) colors_ = false;
  stats_.chunk_voxels += filtered.size();
  const float inv = 1.0f / voxel_;
  for (size_t i = 0; i < filtered.size(); ++i) {
    const auto [it, inserted] = index_.try_emplace(voxel_key(filtered.points[i], inv), std::uint32_t(cells_.size()));
    if (inserted) cells_.emplace_back();
    Cell& c = cells_[it->second];
    c.sum += filtered.points[i];
    if (colors_)
      for (int k = 0; k < 3; ++k) c.rgb[size_t(k)] += filtered.colors[i][size_t(k)];
    ++c.count;
  }
  stats_.peak_points = std::max(stats_.peak_points, cells_.size() + raw_points);
  stats_.filter_ms += filter_ms + sw.ms();
}

ColoredCloud VoxelAccumulator::finish() {
  ColoredCloud out;
  out.points.reserve(cells_.size());
  if (colors_) out.colors.reserve(cells_.size());
  for (const Cell& c : cells_) {
    out.points.push_back(c.sum / float(c.count));
    if (colors_)
      out.colors.push_back({std::uint8_t((c.rgb[0] + c.count / 2) / c.count),
                            std::uint8_t((c.rgb[1] + c.count / 2) / c.count),
                            std::uint8_t((c.rgb[2] + c.count / 2) / c.count)});
  }
  cells_ = {};
  index_ = {};
  return out;
}

}  // namespace cslam
