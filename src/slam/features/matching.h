#pragma once
// Descriptor matching: brute force with the ratio test, BoW-accelerated matching (only features
// under the same vocabulary node), best/second-best search among candidates (matching by
// projection: FeatureGrid::features_in_area + best_match), and the rotation-consistency check.
#include <vector>

#include "slam/bow/bow_vector.h"
#include "slam/features/descriptor.h"
#include "slam/features/feature_grid.h"
#include "slam/features/orb_extractor.h"

namespace cslam {

struct MatchParams {
  int th_low = 50;
  int th_high = 100;
  double nn_ratio = 0.6;
  bool check_orientation = true;
};

// Keeps the indices whose rotation difference falls in the 3 most populated bins of a 30-bin
// histogram (ORB-SLAM2 style): the 2nd and 3rd bins are kept only if they hold at least 10% of
// the most populated one.
class RotationHistogram {
 public:
  explicit RotationHistogram(int bins = 30);
  // Rotation = angle_a - angle_b wrapped to [0,360).
  void add(double angle_a_deg, double angle_b_deg, int match_index);
  std::vector<int> outliers() const;  // match indices NOT in the kept bins (ascending)
  std::vector<int> inliers() const;   // the complement (ascending)

 private:
  std::vector<std::vector<int>> bins_;
  std::vector<int> kept_bins() const;
};

struct Match {
  int a = -1;
  int b = -1;
  int distance = 0;
};

// Brute-force NN with ratio test (a -> b), optional orientation check. mask_a: if non-null only
// a-indices with mask_a[i] != 0 are matched. One-to-one: if two a's pick the same b the closer wins.
// A match needs distance <= th_low and distance < nn_ratio * second best distance.
std::vector<Match> match_brute_force(const OrbFeatures& a, const OrbFeatures& b, const MatchParams& params,
                                     const std::vector<char>* mask_a = nullptr);

// Feature-vector accelerated matching: only between features under the same vocabulary node.
// Each b used at most once (the closer a wins). Same thresholds as match_brute_force.
// Masks as in match_brute_force: non-null -> only indices with mask[i] != 0 take part.
std::vector<Match> match_by_bow(const OrbFeatures& a, const FeatureVector& fa, const OrbFeatures& b,
                                const FeatureVector& fb, const MatchParams& params,
                                const std::vector<char>* mask_a = nullptr, const std::vector<char>* mask_b = nullptr);

// Best and second-best candidate among `candidates` (indices into features) for one descriptor.
// skip: if non-null, candidates with (*skip)[i] != 0 are ignored. second_level is the octave of the
// second-best candidate (ORB-SLAM2 applies the ratio test only when both are on the same level).
struct BestMatch {
  int index = -1;
  int distance = 256;
  int second_distance = 256;
  int second_level = -1;
  int level = -1;
};
BestMatch best_match(const Descriptor& d, const OrbFeatures& features, const std::vector<int>& candidates,
                     const std::vector<char>* skip = nullptr);

// Matching by projection (tracking): each point (e.g. a map point projected into the frame) is
// matched to the best unused frame feature within `radius * scale_factors[level]` pixels of its
// projection (undistorted coordinates) on levels [level-1, level+1]. Accepted if distance <=
// th_high and, when the two best are on the same level, distance <= nn_ratio * second.
// frame_taken: features already matched (non-zero) are skipped. Match.a = point index, .b = feature.
struct ProjectedDescriptor {
  double u = 0, v = 0;
  int level = 0;  // predicted pyramid level
  Descriptor descriptor{};
};
std::vector<Match> match_by_projection(const std::vector<ProjectedDescriptor>& points, const OrbFeatures& frame,
                                       const FeatureGrid& grid, const std::vector<double>& scale_factors, double radius,
                                       const MatchParams& params, const std::vector<char>* frame_taken = nullptr);

// Removes the matches whose rotation is inconsistent (RotationHistogram over keypoint angles).
void filter_by_orientation(const OrbFeatures& a, const OrbFeatures& b, std::vector<Match>& matches);

}  // namespace cslam
