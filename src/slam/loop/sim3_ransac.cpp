#include "slam/loop/sim3_ransac.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "core/error.h"
#include "geometry/alignment.h"

namespace cslam {

namespace {

double reprojection_chi2(const StereoIntrinsics& k, const Eigen::Vector3d& p, const Eigen::Vector2d& uv,
                         double sigma2) {
  if (!(p.z() > 0)) return std::numeric_limits<double>::infinity();
  const double du = k.fx * p.x() / p.z() + k.cx - uv.x();
  const double dv = k.fy * p.y() / p.z() + k.cy - uv.y();
  return (du * du + dv * dv) / sigma2;
}

// Classifies every match under S_12; returns the number of inliers.
int classify(const Sim3& S_12, const std::vector<Sim3Correspondence>& matches, const StereoIntrinsics& k1,
             const StereoIntrinsics& k2, double chi2, std::vector<char>& inlier) {
  inlier.assign(matches.size(), 0);
  int n = 0;
  for (size_t i = 0; i < matches.size(); ++i) {
    const auto e = sim3_match_chi2(S_12, matches[i], k1, k2);
    inlier[i] = e.e1 < chi2 && e.e2 < chi2;
    n += inlier[i];
  }
  return n;
}

// Closed-form estimate from the matches flagged in `inlier`.
bool estimate_on_inliers(const std::vector<Sim3Correspondence>& matches, const std::vector<char>& inlier,
                         bool with_scale, Sim3& S_12) {
  std::vector<Eigen::Vector3d> src, dst;
  for (size_t i = 0; i < matches.size(); ++i)
    if (inlier[i]) {
      src.push_back(matches[i].p2);
      dst.push_back(matches[i].p1);
    }
  const auto u = umeyama(src, dst, with_scale);
  if (u.ok) S_12 = u.T_dst_src;
  return u.ok;
}

// Three points spanning a triangle of reasonable area (collinear samples give no rotation).
bool well_conditioned(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a;
  const double area2 = ab.cross(ac).norm();
  const double longest2 = std::max({ab.squaredNorm(), ac.squaredNorm(), (c - b).squaredNorm()});
  return longest2 > 1e-12 && area2 > 1e-3 * longest2;
}

}  // namespace

Sim3MatchChi2 sim3_match_chi2(const Sim3& S_12, const Sim3Correspondence& m, const StereoIntrinsics& k1,
                              const StereoIntrinsics& k2) {
  // S_21 * p1 = (1/s) R^T (p1 - t), computed without forming the inverse.
  const Eigen::Vector3d p2_in_1 = m.T_view_1 * (S_12 * m.p2);
  const Eigen::Vector3d p1_in_2 = (S_12.rotation().conjugate() * (m.p1 - S_12.translation())) / S_12.scale();
  return {reprojection_chi2(k1, p2_in_1, m.uv1, m.sigma2_1), reprojection_chi2(k2, p1_in_2, m.uv2, m.sigma2_2)};
}

Sim3RansacResult sim3_ransac(const std::vector<Sim3Correspondence>& matches, const StereoIntrinsics& k1,
                             const StereoIntrinsics& k2, const Sim3RansacConfig& cfg) {
  if (cfg.max_iterations < 1) throw ConfigError("sim3_ransac: max_iterations must be >= 1");
  if (!(cfg.probability > 0 && cfg.probability < 1)) throw ConfigError("sim3_ransac: probability must be in (0, 1)");
  if (cfg.min_inliers < 3) throw ConfigError("sim3_ransac: min_inliers must be >= 3");
  if (!(cfg.chi2 > 0)) throw ConfigError("sim3_ransac: chi2 must be > 0");

  Sim3RansacResult res;
  res.inlier.assign(matches.size(), 0);
  const int n = int(matches.size());
  if (n < 3 || n < cfg.min_inliers) return res;

  std::mt19937_64 rng(cfg.seed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  const bool with_scale = !cfg.fix_scale;
  int best_count = 0;
  Sim3 best;
  std::vector<char> scratch;
  int needed = cfg.max_iterations;
  const double log_fail = std::log(1.0 - cfg.probability);
  while (res.iterations < std::min(needed, cfg.max_iterations)) {
    ++res.iterations;
    int idx[3];
    idx[0] = pick(rng);
    do idx[1] = pick(rng);
    while (idx[1] == idx[0]);
    do idx[2] = pick(rng);
    while (idx[2] == idx[0] || idx[2] == idx[1]);
    Eigen::Vector3d src[3], dst[3];
    for (int j = 0; j < 3; ++j) {
      src[j] = matches[idx[j]].p2;
      dst[j] = matches[idx[j]].p1;
    }
    if (!well_conditioned(src[0], src[1], src[2]) || !well_conditioned(dst[0], dst[1], dst[2])) continue;
    const auto u = umeyama(src, dst, 3, with_scale);
    if (!u.ok) continue;
    const int count = classify(u.T_dst_src, matches, k1, k2, cfg.chi2, scratch);
    if (count > best_count) {
      best_count = count;
      best = u.T_dst_src;
      // Adaptive number of samples: P(one all-inlier sample in N draws) >= probability.
      const double w = double(count) / n;
      const double p_good = w * w * w;
      if (p_good >= 1.0) {
        needed = res.iterations;
      } else {
        const double N = log_fail / std::log(1.0 - p_good);
        needed = std::isfinite(N) ? int(std::min<double>(std::ceil(N), cfg.max_iterations)) : cfg.max_iterations;
      }
    }
  }
  if (best_count < std::max(3, cfg.min_inliers)) return res;

  // Re-estimate on all inliers and re-classify (twice: the refit can pick up a few more matches).
  Sim3 S = best;
  std::vector<char> inlier;
  int count = classify(S, matches, k1, k2, cfg.chi2, inlier);
  for (int round = 0; round < 2; ++round) {
    Sim3 refit;
    if (!estimate_on_inliers(matches, inlier, with_scale, refit)) break;
    std::vector<char> refit_inlier;
    const int refit_count = classify(refit, matches, k1, k2, cfg.chi2, refit_inlier);
    if (refit_count < count) break;  // the least-squares refit in 3D can be worse in pixels; keep the better
    S = refit;
    inlier.swap(refit_inlier);
    count = refit_count;
  }
  res.S_12 = S;
  res.inlier = inlier;
  res.num_inliers = count;
  res.success = count >= cfg.min_inliers;
  return res;
}

}  // namespace cslam
