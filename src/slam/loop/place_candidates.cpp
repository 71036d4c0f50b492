#include "slam/loop/place_candidates.h"

#include <algorithm>

#include "slam/bow/vocabulary.h"

namespace cslam {

double min_covisible_score(const KeyFrame& kf) {
  double min_score = 1.0;
  for (KeyFrame* c : kf.covisibles()) min_score = std::min(min_score, Vocabulary::score(kf.data->bow, c->data->bow));
  return min_score;
}

std::vector<ConsistencyChecker::Group> query_candidate_groups(const Map& map, const BowVector& bow, double min_score,
                                                              const std::function<bool(KeyFrameId)>& exclude) {
  KeyFrameDatabase::QueryParams qp;
  qp.min_score = min_score;
  const auto cands = map.database.query(bow, qp, exclude, [&](KeyFrameId id) {
    std::vector<KeyFrameId> out;
    if (auto kf = map.keyframe(id))
      for (KeyFrame* n : kf->best_covisibles(10)) out.push_back(n->id);
    return out;
  });
  std::vector<ConsistencyChecker::Group> groups;
  for (const auto& c : cands) {
    ConsistencyChecker::Group g;
    g.candidate = c.id;
    g.members.push_back(c.id);
    if (auto kf = map.keyframe(c.id))
      for (KeyFrame* n : kf->covisibles()) g.members.push_back(n->id);
    groups.push_back(std::move(g));
  }
  return groups;
}

}  // namespace cslam
