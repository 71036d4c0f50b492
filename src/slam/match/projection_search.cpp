#include "slam/match/projection_search.h"

#include <cmath>

#include "core/pointer_set.h"
#include "slam/features/matching.h"

namespace cslam {

namespace {
constexpr int kThHigh = 100;
constexpr int kThLow = 50;
}  // namespace

ProjectedPoint project_map_point(const MapPoint& mp, const SE3& T_cam_world, const FrameData& f, double min_view_cos) {
  ProjectedPoint r;
  const Eigen::Vector3d pc = T_cam_world * mp.position;
  if (pc.z() <= 0) return r;
  const Eigen::Vector2d uv = f.camera.project(pc);
  if (!f.in_bounds(uv.x(), uv.y())) return r;
  const Eigen::Vector3d center = T_cam_world.inverse().translation();
  const Eigen::Vector3d po = mp.position - center;
  const double dist = po.norm();
  if (dist < mp.min_valid_distance() || dist > mp.max_valid_distance()) return r;
  const double view_cos = po.dot(mp.normal) / dist;
  if (view_cos < min_view_cos) return r;
  r.visible = true;
  r.uv = uv;
  r.u_right = uv.x() - f.rgbd.bf / pc.z();
  r.view_cos = view_cos;
  r.predicted_level = mp.predict_level(dist, *f.pyramid);
  return r;
}

int search_by_projection(Frame& cur, const Frame& last, double th, bool check_orientation) {
  const FrameData& f = *cur.data;
  const SE3& Tcw = cur.T_cam_world;
  const Eigen::Vector3d t_last_cur = (last.T_cam_world * Tcw.inverse()).translation();
  const double bf_over_fx = f.rgbd.bf / f.camera.fx;
  const bool forward = t_last_cur.z() > bf_over_fx;
  const bool backward = -t_last_cur.z() > bf_over_fx;
  RotationHistogram hist;
  std::vector<int> cands;
  int n = 0;
  for (size_t i = 0; i < last.map_points.size(); ++i) {
    const auto& mp = last.map_points[i];
    if (!mp || last.outlier[i] || mp->bad) continue;
    const Eigen::Vector3d pc = Tcw * mp->position;
    if (pc.z() <= 0) continue;
    const Eigen::Vector2d uv = f.camera.project(pc);
    if (!f.in_bounds(uv.x(), uv.y())) continue;
    const int last_octave = last.data->features.keypoints[i].octave;
    const double radius = th * f.pyramid->scale[last_octave];
    if (forward)
      f.grid.features_in_area(uv.x(), uv.y(), radius, last_octave, -1, cands);
    else if (backward)
      f.grid.features_in_area(uv.x(), uv.y(), radius, 0, last_octave, cands);
    else
      f.grid.features_in_area(uv.x(), uv.y(), radius, std::max(0, last_octave - 1), last_octave + 1, cands);
    if (cands.empty()) continue;
    const double ur_pred = uv.x() - f.rgbd.bf / pc.z();
    int best = 256, best_idx = -1;
    for (int idx : cands) {
      if (cur.map_points[idx] && !cur.map_points[idx]->observations.empty()) continue;
      if (f.u_right[idx] > 0 && std::abs(ur_pred - f.u_right[idx]) > radius) continue;
      const int d = hamming_distance(mp->descriptor, f.features.descriptors[idx]);
      if (d < best) {
        best = d;
        best_idx = idx;
      }
    }
    if (best <= kThHigh) {
      cur.map_points[best_idx] = mp;
      cur.outlier[best_idx] = 0;
      ++n;
      if (check_orientation) {
        hist.add(last.data->features.keypoints[i].angle, f.features.keypoints[best_idx].angle, best_idx);
      }
    }
  }
  if (check_orientation) {
    for (int idx : hist.outliers()) {
      cur.map_points[idx].reset();
      --n;
    }
  }
  return n;
}

int search_local_points(Frame& cur, const std::vector<const MapPointPtr*>& points, double th) {
  const FrameData& f = *cur.data;
  PointerSet in_frame;
  in_frame.clear(cur.map_points.size());
  for (const auto& mp : cur.map_points)
    if (mp) in_frame.insert(mp.get());
  std::vector<int> cands;
  int n = 0;
  // The local map's points are spread over the heap, and each is read once: their slots are
  // fetched 2 * kAhead points ahead, the points themselves kAhead ahead, so that the misses
  // overlap the work on the points before them.
  constexpr std::size_t kAhead = 8;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (i + 2 * kAhead < points.size()) __builtin_prefetch(points[i + 2 * kAhead]);
    if (i + kAhead < points.size())
      if (const MapPoint* q = points[i + kAhead]->get()) {
        __builtin_prefetch(&q->position);
        __builtin_prefetch(&q->bad);
      }
    const MapPointPtr& mp = *points[i];
    if (!mp || mp->bad || in_frame.contains(mp.get())) continue;
    const ProjectedPoint p = project_map_point(*mp, cur.T_cam_world, f);
    if (!p.visible) continue;
    ++mp->visible;
    const double r = th * (p.view_cos > 0.998 ? 2.5 : 4.0) * f.pyramid->scale[p.predicted_level];
    f.grid.features_in_area(p.uv.x(), p.uv.y(), r, p.predicted_level - 1, p.predicted_level, cands);
    if (cands.empty()) continue;
    int best = 256, best2 = 256, best_level = -1, best_level2 = -1, best_idx = -1;
    for (int idx : cands) {
      if (cur.map_points[idx] && !cur.map_points[idx]->observations.empty()) continue;
      if (f.u_right[idx] > 0 && std::abs(p.u_right - f.u_right[idx]) > r) continue;
      const int d = hamming_distance(mp->descriptor, f.features.descriptors[idx]);
      const int level = f.features.keypoints[idx].octave;
      if (d < best) {
        best2 = best;
        best_level2 = best_level;
        best = d;
        best_level = level;
        best_idx = idx;
      } else if (d < best2) {
        best2 = d;
        best_level2 = level;
      }
    }
    if (best > kThHigh) continue;
    if (best_level == best_level2 && best > 0.8 * best2) continue;
    cur.map_points[best_idx] = mp;
    cur.outlier[best_idx] = 0;
    ++n;
  }
  return n;
}

int search_by_bow(const KeyFrame& kf, const FrameData& f, std::vector<MapPointPtr>& matches, double nn_ratio,
                  bool check_orientation) {
  matches.assign(f.size(), nullptr);
  const auto& kf_fv = kf.data->feature_vector;
  RotationHistogram hist;
  int n = 0;
  auto kit = kf_fv.begin();
  auto fit = f.feature_vector.begin();
  while (kit != kf_fv.end() && fit != f.feature_vector.end()) {
    if (kit->first < fit->first) {
      kit = kf_fv.lower_bound(fit->first);
      continue;
    }
    if (fit->first < kit->first) {
      fit = f.feature_vector.lower_bound(kit->first);
      continue;
    }
    for (int ki : kit->second) {
      const auto& mp = kf.map_points[ki];
      if (!mp || mp->bad) continue;
      const Descriptor& d_kf = kf.data->features.descriptors[ki];
      int best = 256, best2 = 256, best_idx = -1;
      for (int fi : fit->second) {
        if (matches[fi]) continue;
        const int d = hamming_distance(d_kf, f.features.descriptors[fi]);
        if (d < best) {
          best2 = best;
          best = d;
          best_idx = fi;
        } else if (d < best2) {
          best2 = d;
        }
      }
      if (best <= kThLow && best < nn_ratio * best2) {
        matches[best_idx] = mp;
        ++n;
        if (check_orientation)
          hist.add(kf.data->features.keypoints[ki].angle, f.features.keypoints[best_idx].angle, best_idx);
      }
    }
    ++kit;
    ++fit;
  }
  if (check_orientation)
    for (int idx : hist.outliers()) {
      matches[idx].reset();
      --n;
    }
  return n;
}

int search_by_projection_keyframe(Frame& cur, const KeyFrame& source, const std::set<MapPoint*>& already, double th,
                                  int max_distance) {
  const FrameData& f = *cur.data;
  const Eigen::Vector3d center = cur.center();
  int n = 0;
  for (const auto& mp : source.map_points) {
    if (!mp || mp->bad || already.count(mp.get())) continue;
    const Eigen::Vector3d pc = cur.T_cam_world * mp->position;
    if (pc.z() <= 0) continue;
    const Eigen::Vector2d uv = f.camera.project(pc);
    if (!f.in_bounds(uv.x(), uv.y())) continue;
    const double dist = (mp->position - center).norm();
    if (dist < mp->min_valid_distance() || dist > mp->max_valid_distance()) continue;
    const int level = mp->predict_level(dist, *f.pyramid);
    const double r = th * f.pyramid->scale[level];
    const auto cands = f.grid.features_in_area(uv.x(), uv.y(), r, level - 1, level + 1);
    int best = 256, best_idx = -1;
    for (int idx : cands) {
      if (cur.map_points[idx]) continue;
      const int d = hamming_distance(mp->descriptor, f.features.descriptors[idx]);
      if (d < best) {
        best = d;
        best_idx = idx;
      }
    }
    if (best <= max_distance) {
      cur.map_points[best_idx] = mp;
      cur.outlier[best_idx] = 0;
      ++n;
    }
  }
  return n;
}

int match_point_in_keyframe(const MapPoint& mp, const KeyFrame& kf, double th) {
  const FrameData& f = *kf.data;
  const Eigen::Vector3d pc = kf.T_cam_world * mp.position;
  if (pc.z() <= 0) return -1;
  const Eigen::Vector2d uv = f.camera.project(pc);
  if (!f.in_bounds(uv.x(), uv.y())) return -1;
  const Eigen::Vector3d po = mp.position - kf.center();
  const double dist = po.norm();
  if (dist < mp.min_valid_distance() || dist > mp.max_valid_distance()) return -1;
  if (po.dot(mp.normal) < 0.5 * dist) return -1;
  const int level = mp.predict_level(dist, *f.pyramid);
  const double r = th * f.pyramid->scale[level];
  // Levels level - 1 and level only, told apart by the grid's own copy of each keypoint's level
  // (reading the keypoint itself is a cache miss).
  const auto cands = f.grid.features_in_area(uv.x(), uv.y(), r, level - 1, level);
  const double ur = uv.x() - f.rgbd.bf / pc.z();
  int best = 256, best_idx = -1;
  for (int idx : cands) {
    const auto& kp = f.features.keypoints[idx];
    const double ex = uv.x() - f.features.undistorted[idx].x(), ey = uv.y() - f.features.undistorted[idx].y();
    double e2 = ex * ex + ey * ey;
    double th_chi2 = 5.99;
    if (f.u_right[idx] >= 0) {
      const double er = ur - f.u_right[idx];
      e2 += er * er;
      th_chi2 = 7.8;
    }
    if (e2 * f.pyramid->inv_sigma2[kp.octave] > th_chi2) continue;
    const int d = hamming_distance(mp.descriptor, f.features.descriptors[idx]);
    if (d < best) {
      best = d;
      best_idx = idx;
    }
  }
  return best <= kThLow ? best_idx : -1;
}

std::vector<FuseMatch> match_for_fuse(KeyFrame* kf, const std::vector<MapPointPtr>& points, double th) {
  std::vector<FuseMatch> matches;
  for (const auto& mp : points) {
    if (!mp || mp->bad || mp->in_keyframe(kf)) continue;
    const int best_idx = match_point_in_keyframe(*mp, *kf, th);
    if (best_idx >= 0) matches.push_back({mp, best_idx});
  }
  return matches;
}

int apply_fuse(Map& map, KeyFrame* kf, const std::vector<FuseMatch>& matches) {
  int n = 0;
  for (const auto& [mp, best_idx] : matches) {
    if (mp->bad || mp->in_keyframe(kf)) continue;
    if (auto existing = kf->map_points[best_idx]; existing && !existing->bad) {
      if (existing->observations.size() > mp->observations.size())
        map.replace_map_point(mp, existing);
      else
        map.replace_map_point(existing, mp);
    } else {
      Map::add_observation(kf, best_idx, mp);
    }
    ++n;
  }
  return n;
}

int fuse(Map& map, KeyFrame* kf, const std::vector<MapPointPtr>& points, double th) {
  return apply_fuse(map, kf, match_for_fuse(kf, points, th));
}

}  // namespace cslam
