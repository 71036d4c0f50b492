#include "cloud/filters.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>

#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

namespace cslam {

namespace {

using PclCloud = pcl::PointCloud<pcl::PointXYZRGB>;

PclCloud::Ptr to_pcl(const ColoredCloud& in) {
  PclCloud::Ptr out(new PclCloud);
  out->resize(in.size());
  for (size_t i = 0; i < in.size(); ++i) {
    auto& q = (*out)[i];
    q.x = in.points[i].x();
    q.y = in.points[i].y();
    q.z = in.points[i].z();
    if (in.has_colors()) {
      q.r = in.colors[i][0];
      q.g = in.colors[i][1];
      q.b = in.colors[i][2];
    } else {
      q.r = q.g = q.b = 0;
    }
    q.a = 255;
  }
  out->width = std::uint32_t(out->size());
  out->height = 1;
  out->is_dense = true;
  return out;
}

void append_from_pcl(const PclCloud& in, bool colors, ColoredCloud& out) {
  out.points.reserve(out.points.size() + in.size());
  if (colors) out.colors.reserve(out.colors.size() + in.size());
  for (const auto& q : in) {
    out.points.emplace_back(q.x, q.y, q.z);
    if (colors) out.colors.push_back({q.r, q.g, q.b});
  }
}

// PCL refuses (and returns the input unchanged) if the voxel index range overflows int32.
constexpr std::int64_t kMaxVoxels = std::int64_t(std::numeric_limits<std::int32_t>::max()) / 4;

void filter_recursive(const PclCloud::Ptr& in, float voxel, bool colors, ColoredCloud& out) {
  if (in->empty()) return;
  Eigen::Vector3f lo_v = in->front().getVector3fMap(), hi_v = lo_v;
  for (const auto& q : *in) {
    lo_v = lo_v.cwiseMin(q.getVector3fMap());
    hi_v = hi_v.cwiseMax(q.getVector3fMap());
  }
  Eigen::Matrix<std::int64_t, 3, 1> span;
  for (int k = 0; k < 3; ++k)
    span[k] = std::int64_t(std::floor(hi_v[k] / voxel)) - std::int64_t(std::floor(lo_v[k] / voxel)) + 2;
  if (span[0] * span[1] * span[2] <= kMaxVoxels) {
    pcl::VoxelGrid<pcl::PointXYZRGB> grid;
    grid.setInputCloud(in);
    grid.setLeafSize(voxel, voxel, voxel);
    PclCloud filtered;
    grid.filter(filtered);
    append_from_pcl(filtered, colors, out);
    return;
  }
  // Split at a voxel boundary across the longest axis.
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (span[k] > span[axis]) axis = k;
  const float split = std::floor(0.5f * (lo_v[axis] + hi_v[axis]) / voxel) * voxel;
  PclCloud::Ptr a(new PclCloud), b(new PclCloud);
  for (const auto& q : *in) (q.getVector3fMap()[axis] < split ? a : b)->push_back(q);
  filter_recursive(a, voxel, colors, out);
  filter_recursive(b, voxel, colors, out);
}

}  // namespace

ColoredCloud voxel_filter(const ColoredCloud& cloud, float voxel_size) {
  if (!(voxel_size > 0) || !std::isfinite(voxel_size))
    throw std::invalid_argument("voxel_filter: voxel size must be positive");
  ColoredCloud out;
  if (cloud.empty()) return out;
  filter_recursive(to_pcl(cloud), voxel_size, cloud.has_colors(), out);
  return out;
}

ColoredCloud remove_statistical_outliers(const ColoredCloud& cloud, const OutlierConfig& config) {
  if (config.mean_k < 1 || !(config.stddev_mul > 0))
    throw std::invalid_argument("remove_statistical_outliers: mean_k >= 1 and stddev_mul > 0 required");
  ColoredCloud out;
  if (cloud.size() <= size_t(config.mean_k)) return cloud;
  pcl::StatisticalOutlierRemoval<pcl::PointXYZRGB> sor;
  sor.setInputCloud(to_pcl(cloud));
  sor.setMeanK(config.mean_k);
  sor.setStddevMulThresh(config.stddev_mul);
  PclCloud kept;
  sor.filter(kept);
  append_from_pcl(kept, cloud.has_colors(), out);
  return out;
}

}  // namespace cslam
