#include "slam/features/matching.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace cslam {

RotationHistogram::RotationHistogram(int bins) {
  if (bins < 3) throw std::invalid_argument("RotationHistogram: need at least 3 bins");
  bins_.resize(bins);
}

void RotationHistogram::add(double angle_a_deg, double angle_b_deg, int match_index) {
  double rot = std::fmod(angle_a_deg - angle_b_deg, 360.0);
  if (rot < 0) rot += 360.0;
  if (!std::isfinite(rot)) return;
  const int n = int(bins_.size());
  const int bin = std::min(n - 1, int(rot * n / 360.0));
  bins_[bin].push_back(match_index);
}

std::vector<int> RotationHistogram::kept_bins() const {
  int m1 = -1, m2 = -1, m3 = -1;
  auto size = [&](int i) { return i < 0 ? 0 : int(bins_[i].size()); };
  for (int i = 0; i < int(bins_.size()); ++i) {
    const int s = size(i);
    if (s > size(m1)) {
      m3 = m2;
      m2 = m1;
      m1 = i;
    } else if (s > size(m2)) {
      m3 = m2;
      m2 = i;
    } else if (s > size(m3)) {
      m3 = i;
    }
  }
  std::vector<int> kept;
  if (m1 < 0 || size(m1) == 0) return kept;
  kept.push_back(m1);
  if (m2 >= 0 && size(m2) >= 0.1 * size(m1)) kept.push_back(m2);
  if (m3 >= 0 && size(m3) >= 0.1 * size(m1)) kept.push_back(m3);
  return kept;
}

std::vector<int> RotationHistogram::outliers() const {
  const std::vector<int> kept = kept_bins();
  std::vector<int> out;
  for (int i = 0; i < int(bins_.size()); ++i)
    if (std::find(kept.begin(), kept.end(), i) == kept.end()) out.insert(out.end(), bins_[i].begin(), bins_[i].end());
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<int> RotationHistogram::inliers() const {
  std::vector<int> out;
  for (int i : kept_bins()) out.insert(out.end(), bins_[i].begin(), bins_[i].end());
  std::sort(out.begin(), out.end());
  return out;
}

BestMatch best_match(const Descriptor& d, const OrbFeatures& features, const std::vector<int>& candidates,
                     const std::vector<char>* skip) {
  BestMatch best;
  for (int i : candidates) {
    if (skip && (*skip)[i]) continue;
    const int dist = hamming_distance(d, features.descriptors[i]);
    const int level = features.keypoints[i].octave;
    if (dist < best.distance) {
      best.second_distance = best.distance;
      best.second_level = best.level;
      best.distance = dist;
      best.index = i;
      best.level = level;
    } else if (dist < best.second_distance) {
      best.second_distance = dist;
      best.second_level = level;
    }
  }
  return best;
}

void filter_by_orientation(const OrbFeatures& a, const OrbFeatures& b, std::vector<Match>& matches) {
  RotationHistogram hist;
  for (int i = 0; i < int(matches.size()); ++i)
    hist.add(a.keypoints[matches[i].a].angle, b.keypoints[matches[i].b].angle, i);
  const std::vector<int> keep = hist.inliers();
  std::vector<Match> kept;
  kept.reserve(keep.size());
  for (int i : keep) kept.push_back(matches[i]);
  std::sort(kept.begin(), kept.end(), [](const Match& x, const Match& y) { return x.a < y.a; });
  matches.swap(kept);
}

namespace {

// Collects accepted a->b pairs keeping every b at most once (closest a wins).
class OneToOne {
 public:
  explicit OneToOne(std::size_t nb) : owner_(nb, -1) {}
  void offer(int a, int b, int distance) {
    int& o = owner_[b];
    if (o >= 0) {
      if (matches_[o].distance <= distance) return;
      matches_[o].a = -1;  // displaced
    }
    o = int(matches_.size());
    matches_.push_back({a, b, distance});
  }
  std::vector<Match> take() {
    std::vector<Match> out;
    for (const Match& m : matches_)
      if (m.a >= 0) out.push_back(m);
    std::sort(out.begin(), out.end(), [](const Match& x, const Match& y) { return x.a < y.a; });
    return out;
  }

 private:
  std::vector<int> owner_;
  std::vector<Match> matches_;
};

bool accept(const BestMatch& m, const MatchParams& p) {
  return m.index >= 0 && m.distance <= p.th_low && double(m.distance) < p.nn_ratio * double(m.second_distance);
}

}  // namespace

std::vector<Match> match_brute_force(const OrbFeatures& a, const OrbFeatures& b, const MatchParams& params,
                                     const std::vector<char>* mask_a) {
  OneToOne pairs(b.size());
  for (int i = 0; i < int(a.size()); ++i) {
    if (mask_a && !(*mask_a)[i]) continue;
    BestMatch m;
    for (int j = 0; j < int(b.size()); ++j) {
      const int dist = hamming_distance(a.descriptors[i], b.descriptors[j]);
      if (dist < m.distance) {
        m.second_distance = m.distance;
        m.distance = dist;
        m.index = j;
      } else if (dist < m.second_distance) {
        m.second_distance = dist;
      }
    }
    if (accept(m, params)) pairs.offer(i, m.index, m.distance);
  }
  std::vector<Match> out = pairs.take();
  if (params.check_orientation) filter_by_orientation(a, b, out);
  return out;
}

std::vector<Match> match_by_bow(const OrbFeatures& a, const FeatureVector& fa, const OrbFeatures& b,
                                const FeatureVector& fb, const MatchParams& params, const std::vector<char>* mask_a,
                                const std::vector<char>* mask_b) {
  OneToOne pairs(b.size());
  auto ia = fa.begin();
  auto ib = fb.begin();
  while (ia != fa.end() && ib != fb.end()) {
    if (ia->first < ib->first) {
      ia = fa.lower_bound(ib->first);
      continue;
    }
    if (ib->first < ia->first) {
      ib = fb.lower_bound(ia->first);
      continue;
    }
    for (int i : ia->second) {
      if (mask_a && !(*mask_a)[i]) continue;
      BestMatch m;
      for (int j : ib->second) {
        if (mask_b && !(*mask_b)[j]) continue;  // mask: non-zero = may be matched
        const int dist = hamming_distance(a.descriptors[i], b.descriptors[j]);
        if (dist < m.distance) {
          m.second_distance = m.distance;
          m.distance = dist;
          m.index = j;
        } else if (dist < m.second_distance) {
          m.second_distance = dist;
        }
      }
      if (accept(m, params)) pairs.offer(i, m.index, m.distance);
    }
    ++ia;
    ++ib;
  }
  std::vector<Match> out = pairs.take();
  if (params.check_orientation) filter_by_orientation(a, b, out);
  return out;
}

std::vector<Match> match_by_projection(const std::vector<ProjectedDescriptor>& points, const OrbFeatures& frame,
                                       const FeatureGrid& grid, const std::vector<double>& scale_factors, double radius,
                                       const MatchParams& params, const std::vector<char>* frame_taken) {
  OneToOne pairs(frame.size());
  const int max_level = int(scale_factors.size()) - 1;
  for (int i = 0; i < int(points.size()); ++i) {
    const ProjectedDescriptor& p = points[i];
    const int level = std::clamp(p.level, 0, std::max(0, max_level));
    const double r = radius * (scale_factors.empty() ? 1.0 : scale_factors[level]);
    const std::vector<int> candidates = grid.features_in_area(p.u, p.v, r, std::max(0, level - 1), level + 1);
    const BestMatch m = best_match(p.descriptor, frame, candidates, frame_taken);
    if (m.index < 0 || m.distance > params.th_high) continue;
    if (m.level == m.second_level && double(m.distance) > params.nn_ratio * double(m.second_distance)) continue;
    pairs.offer(i, m.index, m.distance);
  }
  return pairs.take();
}

}  // namespace cslam
