#include "eval/trajectory_eval.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "io/tum_dataset.h"

namespace cslam {

Alignment parse_alignment(const std::string& text) {
  if (text == "none") return Alignment::kNone;
  if (text == "se3") return Alignment::kSE3;
  if (text == "sim3") return Alignment::kSim3;
  throw ConfigError("unknown alignment '" + text + "' (use se3, sim3 or none)");
}

std::vector<std::pair<int, int>> associate_trajectories(const Trajectory& gt, const Trajectory& est, double max_dt) {
  std::vector<double> a, b;
  for (const auto& p : gt) a.push_back(p.timestamp);
  for (const auto& p : est) b.push_back(p.timestamp);
  // associate_timestamps needs sorted input; trajectories of several clients may not be.
  std::vector<int> ia(a.size()), ib(b.size());
  for (size_t i = 0; i < ia.size(); ++i) ia[i] = int(i);
  for (size_t i = 0; i < ib.size(); ++i) ib[i] = int(i);
  std::stable_sort(ia.begin(), ia.end(), [&](int x, int y) { return a[x] < a[y]; });
  std::stable_sort(ib.begin(), ib.end(), [&](int x, int y) { return b[x] < b[y]; });
  std::vector<double> sa, sb;
  for (int i : ia) sa.push_back(a[i]);
  for (int i : ib) sb.push_back(b[i]);
  std::vector<std::pair<int, int>> out;
  for (const auto& [i, j] : associate_timestamps(sa, sb, max_dt)) out.emplace_back(ia[i], ib[j]);
  return out;
}

AteResult compute_ate(const Trajectory& gt, const Trajectory& est, Alignment align, double max_dt) {
  return compute_ate_joint({{gt, est}}, align, max_dt);
}

AteResult compute_ate_joint(const std::vector<std::pair<Trajectory, Trajectory>>& trajectory_pairs, Alignment align,
                            double max_dt) {
  std::vector<Eigen::Vector3d> src, dst;
  std::vector<double> times;
  for (const auto& [gt, est] : trajectory_pairs) {
    auto pairs = associate_trajectories(gt, est, max_dt);
    std::sort(pairs.begin(), pairs.end(),
              [&](auto x, auto y) { return est[x.second].timestamp < est[y.second].timestamp; });
    for (const auto& [i, j] : pairs) {
      dst.push_back(gt[i].T_world_cam.translation());
      src.push_back(est[j].T_world_cam.translation());
      times.push_back(est[j].timestamp);
    }
  }
  if (src.size() < 3)
    throw InputError(
        "ATE", "only " + std::to_string(src.size()) +
                   " poses associate between ground truth and estimate (need >= 3; check timestamps and --max-dt)");
  AteResult r;
  if (align != Alignment::kNone) {
    const auto u = umeyama(src, dst, align == Alignment::kSim3);
    if (!u.ok) throw InputError("ATE", "alignment failed: the estimate's positions are degenerate (all identical?)");
    r.T_gt_est = u.T_dst_src;
  }
  for (size_t k = 0; k < src.size(); ++k) {
    r.errors.push_back((r.T_gt_est * src[k] - dst[k]).norm());
    r.timestamps.push_back(times[k]);
  }
  r.stats = compute_stats(r.errors);
  return r;
}

RpeResult compute_rpe(const Trajectory& gt, const Trajectory& est, double delta_s, double max_dt) {
  auto pairs = associate_trajectories(gt, est, max_dt);
  std::sort(pairs.begin(), pairs.end(),
            [&](auto x, auto y) { return est[x.second].timestamp < est[y.second].timestamp; });
  std::vector<double> terr, rerr;
  size_t j = 0;
  for (size_t i = 0; i < pairs.size(); ++i) {
    const double target = est[pairs[i].second].timestamp + delta_s;
    if (j < i) j = i;
    while (j + 1 < pairs.size() && est[pairs[j + 1].second].timestamp <= target) ++j;
    // j is the last pose at or before target; pick the closer of j and j+1.
    size_t best = j;
    if (j + 1 < pairs.size() &&
        std::abs(est[pairs[j + 1].second].timestamp - target) < std::abs(est[pairs[j].second].timestamp - target))
      best = j + 1;
    if (best <= i || std::abs(est[pairs[best].second].timestamp - target) > std::max(max_dt, 0.5 * delta_s)) continue;
    const SE3 dg = gt[pairs[i].first].T_world_cam.inverse() * gt[pairs[best].first].T_world_cam;
    const SE3 de = est[pairs[i].second].T_world_cam.inverse() * est[pairs[best].second].T_world_cam;
    const SE3 err = dg.inverse() * de;
    terr.push_back(err.translation().norm());
    rerr.push_back(err.rotation_angle() * 180.0 / M_PI);
  }
  if (terr.empty())
    throw InputError("RPE", "no pose pairs " + std::to_string(delta_s) + " s apart associate with ground truth");
  return {compute_stats(terr), compute_stats(rerr)};
}

}  // namespace cslam
