#include "slam/loop/overlap_verifier.h"

#include <set>

#include "slam/features/matching.h"
#include "slam/loop/sim3_refine.h"

namespace cslam {

namespace {

StereoIntrinsics intrinsics_of(const KeyFrame& kf) {
  const auto& c = kf.data->camera;
  return {c.fx, c.fy, c.cx, c.cy, kf.data->rgbd.bf};
}

std::vector<char> has_point_mask(const KeyFrame& kf) {
  std::vector<char> mask(kf.map_points.size(), 0);
  for (size_t i = 0; i < mask.size(); ++i) mask[i] = kf.map_points[i] && !kf.map_points[i]->bad;
  return mask;
}

// The candidate keyframe's and its neighbours' map points, each once.
std::set<MapPoint*, ById> candidate_points(const KeyFrame& candidate, const std::vector<KeyFrame*>& neighbours) {
  std::set<MapPoint*, ById> points;
  auto collect = [&](const KeyFrame& kf) {
    for (const auto& mp : kf.map_points)
      if (mp && !mp->bad) points.insert(mp.get());
  };
  collect(candidate);
  for (KeyFrame* n : neighbours)
    if (n && !n->bad) collect(*n);
  return points;
}

// Projects the candidate group's points into `query` with S (query-camera <- candidate-camera)
// and matches them to keypoints by descriptor. Matched keypoints with depth give extra 3D-3D
// correspondences for a second refinement. Returns the number of matches.
int projection_matches(const KeyFrame& query, const KeyFrame& candidate, const std::set<MapPoint*, ById>& points,
                       const Sim3& S_q_c, double radius, std::vector<Sim3Correspondence>& extra) {
  const FrameData& f = *query.data;
  const FrameData& fc = *candidate.data;
  std::vector<char> used(f.size(), 0);
  int matched = 0;
  const SE3 T_c_w = candidate.T_cam_world;
  for (MapPoint* mp : points) {
    const Eigen::Vector3d pc = T_c_w * mp->position;
    const Eigen::Vector3d pq = S_q_c * pc;
    if (pq.z() <= 0.1 || pc.z() <= 0.1) continue;
    const Eigen::Vector2d uv = f.camera.project(pq);
    if (!f.in_bounds(uv.x(), uv.y())) continue;
    const double dist = pq.norm();
    if (dist < mp->min_valid_distance() || dist > mp->max_valid_distance()) continue;
    const int level = mp->predict_level(dist, *f.pyramid);
    const auto cands = f.grid.features_in_area(uv.x(), uv.y(), radius * f.pyramid->scale[level], level - 1, level + 1);
    int best = 256, best_idx = -1;
    for (int idx : cands) {
      if (used[idx]) continue;
      const int d = hamming_distance(mp->descriptor, f.features.descriptors[idx]);
      if (d < best) {
        best = d;
        best_idx = idx;
      }
    }
    if (best > 50) continue;
    used[best_idx] = 1;
    ++matched;
    if (!f.has_depth(best_idx)) continue;
    Sim3Correspondence c;
    c.p1 = f.unproject(best_idx);
    c.p2 = pc;
    c.uv1 = f.features.undistorted[best_idx];
    c.uv2 = fc.camera.project(pc);
    c.sigma2_1 = f.pyramid->sigma2[f.features.keypoints[best_idx].octave];
    c.sigma2_2 = c.sigma2_1;
    extra.push_back(c);
  }
  return matched;
}

// Window refinement: the query's inlier correspondences, plus projection matches of the candidate
// group's points in each of the query's best covisible keyframes, seen from that keyframe
// (Sim3Correspondence::T_view_1), all in one fit of S_query_candidate. Kept only when it explains
// at least as many observations as the query-only fit did.
void refine_over_window(const KeyFrame& query, const KeyFrame& candidate, const std::set<MapPoint*, ById>& points,
                        const StereoIntrinsics& kq, const StereoIntrinsics& kc, const OverlapVerifyConfig& cfg,
                        const std::vector<Sim3Correspondence>& query_matches, const Sim3RefineResult& query_fit,
                        OverlapVerifyResult& r) {
  if (cfg.window_keyframes <= 0) return;
  std::vector<Sim3Correspondence> pooled;
  for (size_t i = 0; i < query_matches.size(); ++i)
    if (query_fit.inlier[i]) pooled.push_back(query_matches[i]);
  int views = 1;
  for (KeyFrame* view : query.best_covisibles(std::size_t(cfg.window_keyframes))) {
    if (!view || view->bad || view->data->camera.width != query.data->camera.width) continue;
    const SE3 T_view_q = view->T_cam_world * query.T_world_cam();
    std::vector<Sim3Correspondence> seen;
    projection_matches(*view, candidate, points, Sim3(T_view_q) * query_fit.S_12, cfg.projection_radius, seen);
    if (seen.empty()) continue;
    const SE3 T_q_view = T_view_q.inverse();
    for (auto& c : seen) {
      c.p1 = T_q_view * c.p1;
      c.T_view_1 = T_view_q;
      pooled.push_back(c);
    }
    ++views;
  }
  if (views == 1) return;
  const Sim3RefineResult fit = refine_sim3(query_fit.S_12, pooled, kq, kc, cfg.ransac.fix_scale);
  // The query's own inliers under the window fit: the window must not trade them away.
  int query_kept = 0;
  for (size_t i = 0, j = 0; i < query_matches.size(); ++i)
    if (query_fit.inlier[i]) query_kept += fit.inlier[j++];
  if (query_kept < cfg.min_final_inliers || fit.num_inliers < query_fit.num_inliers) return;
  r.S_query_candidate = fit.S_12;
  r.window_keyframes = views;
  r.window_inliers = fit.num_inliers;
}

}  // namespace

OverlapVerifyResult verify_overlap(const KeyFrame& query, const KeyFrame& candidate,
                                   const std::vector<KeyFrame*>& candidate_neighbours, const OverlapVerifyConfig& cfg) {
  OverlapVerifyResult r;
  const FrameData& fq = *query.data;
  const FrameData& fc = *candidate.data;
  MatchParams mp;
  mp.nn_ratio = 0.75;
  mp.th_low = 50;
  mp.check_orientation = true;
  const auto mask_q = has_point_mask(query), mask_c = has_point_mask(candidate);
  const auto matches =
      match_by_bow(fq.features, fq.feature_vector, fc.features, fc.feature_vector, mp, &mask_q, &mask_c);
  r.bow_matches = int(matches.size());
  if (r.bow_matches < cfg.min_bow_matches) {
    r.reason = "too few BoW matches";
    return r;
  }
  std::vector<Sim3Correspondence> corr;
  corr.reserve(matches.size());
  for (const auto& m : matches) {
    Sim3Correspondence c;
    c.p1 = query.T_cam_world * query.map_points[m.a]->position;
    c.p2 = candidate.T_cam_world * candidate.map_points[m.b]->position;
    c.uv1 = fq.features.undistorted[m.a];
    c.uv2 = fc.features.undistorted[m.b];
    c.sigma2_1 = fq.pyramid->sigma2[fq.features.keypoints[m.a].octave];
    c.sigma2_2 = fc.pyramid->sigma2[fc.features.keypoints[m.b].octave];
    corr.push_back(c);
  }
  const StereoIntrinsics kq = intrinsics_of(query), kc = intrinsics_of(candidate);
  const Sim3RansacResult ransac = sim3_ransac(corr, kq, kc, cfg.ransac);
  r.ransac_inliers = ransac.num_inliers;
  if (!ransac.success) {
    r.reason = "RANSAC found no consistent transform";
    return r;
  }
  const Sim3RefineResult refined = refine_sim3(ransac.S_12, corr, kq, kc, cfg.ransac.fix_scale);
  r.refined_inliers = refined.num_inliers;
  if (refined.num_inliers < cfg.min_refined_inliers) {
    r.reason = "too few inliers after refinement";
    return r;
  }
  std::vector<Sim3Correspondence> extra;
  const auto points = candidate_points(candidate, candidate_neighbours);
  r.projection_matches = projection_matches(query, candidate, points, refined.S_12, cfg.projection_radius, extra);
  if (r.projection_matches < cfg.min_projection_matches) {
    r.reason = "projection check failed";
    return r;
  }
  // Second refinement on the BoW inliers plus every match the projection found.
  std::vector<Sim3Correspondence> all;
  for (size_t i = 0; i < corr.size(); ++i)
    if (refined.inlier[i]) all.push_back(corr[i]);
  all.insert(all.end(), extra.begin(), extra.end());
  const Sim3RefineResult final_fit = refine_sim3(refined.S_12, all, kq, kc, cfg.ransac.fix_scale);
  r.final_inliers = final_fit.num_inliers;
  if (final_fit.num_inliers < cfg.min_final_inliers) {
    r.reason = "too few inliers after the projection refinement";
    return r;
  }
  r.S_query_candidate = final_fit.S_12;
  r.accepted = true;
  refine_over_window(query, candidate, points, kq, kc, cfg, all, final_fit, r);
  return r;
}

}  // namespace cslam
