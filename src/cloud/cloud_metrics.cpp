#include "cloud/cloud_metrics.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <thread>

#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

namespace cslam {

std::vector<float> nearest_distances(const std::vector<Eigen::Vector3f>& queries,
                                     const std::vector<Eigen::Vector3f>& targets, int threads) {
  if (targets.empty()) throw std::invalid_argument("nearest_distances: target cloud is empty");
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->resize(targets.size());
  for (size_t i = 0; i < targets.size(); ++i) (*cloud)[i].getVector3fMap() = targets[i];
  cloud->width = std::uint32_t(targets.size());
  cloud->height = 1;
  pcl::KdTreeFLANN<pcl::PointXYZ> tree(false);  // unsorted results: only one neighbour is asked for
  tree.setInputCloud(cloud);

  std::vector<float> out(queries.size(), 0.0f);
  auto work = [&](size_t begin, size_t end) {
    pcl::Indices idx(1);
    std::vector<float> sq(1);
    pcl::PointXYZ q;
    for (size_t i = begin; i < end; ++i) {
      q.getVector3fMap() = queries[i];
      tree.nearestKSearch(q, 1, idx, sq);
      out[i] = std::sqrt(sq[0]);
    }
  };
  const size_t n = queries.size();
  const int t = std::max(1, std::min<int>(threads, int(n / 1000) + 1));
  std::vector<std::thread> pool;
  for (int k = 1; k < t; ++k) pool.emplace_back(work, n * k / t, n * (k + 1) / t);
  work(0, n / t);
  for (auto& th : pool) th.join();
  return out;
}

DistanceStats distance_stats(std::vector<float> d) {
  DistanceStats s;
  s.n = int(d.size());
  if (d.empty()) return s;
  std::sort(d.begin(), d.end());
  double sum = 0, sq = 0;
  for (float v : d) {
    sum += v;
    sq += double(v) * v;
  }
  const size_t n = d.size();
  s.mean = sum / n;
  s.rmse = std::sqrt(sq / n);
  s.median = n % 2 ? d[n / 2] : 0.5 * (double(d[n / 2 - 1]) + d[n / 2]);
  s.p95 = d[std::min(n - 1, size_t(std::ceil(0.95 * n)) - 1)];
  s.max = d.back();
  return s;
}

BboxMatch compute_bbox_match(const std::vector<Eigen::Vector3f>& ref, const std::vector<Eigen::Vector3f>& test) {
  const BoundingBox br = bounding_box(ref), bt = bounding_box(test);
  BboxMatch m;
  m.center_ref = br.center();
  m.center_test = bt.center();
  m.scale = bt.diagonal() > 0 ? double(br.diagonal()) / bt.diagonal() : 1.0;
  return m;
}

CloudComparison compare_clouds(const std::vector<Eigen::Vector3f>& ref, const std::vector<Eigen::Vector3f>& test_in,
                               const CloudCompareConfig& config) {
  if (ref.empty()) throw std::invalid_argument("compare_clouds: reference cloud is empty");
  if (test_in.empty()) throw std::invalid_argument("compare_clouds: test cloud is empty");
  CloudComparison r;
  r.ref_points = ref.size();
  r.test_points = test_in.size();
  std::vector<Eigen::Vector3f> matched;
  const std::vector<Eigen::Vector3f>* test = &test_in;
  if (config.match_bbox) {
    r.bbox_matched = true;
    r.bbox = compute_bbox_match(ref, test_in);
    matched.reserve(test_in.size());
    for (const auto& p : test_in) matched.push_back(r.bbox.apply(p));
    test = &matched;
  }
  const std::vector<float> t2r = nearest_distances(*test, ref, config.threads);
  const std::vector<float> r2t = nearest_distances(ref, *test, config.threads);
  for (double thr : config.completeness_thresholds) {
    const size_t within = size_t(std::count_if(r2t.begin(), r2t.end(), [&](float d) { return d <= thr; }));
    r.completeness.emplace_back(thr, double(within) / double(r2t.size()));
  }
  r.test_to_ref = distance_stats(t2r);
  r.ref_to_test = distance_stats(r2t);
  r.hausdorff_test_to_ref = r.test_to_ref.max;
  r.hausdorff_ref_to_test = r.ref_to_test.max;
  r.hausdorff_symmetric = std::max(r.hausdorff_test_to_ref, r.hausdorff_ref_to_test);
  return r;
}

}  // namespace cslam
