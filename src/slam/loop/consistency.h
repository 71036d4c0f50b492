#pragma once
// Temporal consistency of place-recognition candidates (loop closing and map fusion).
// Each update() gets the current query keyframe's candidate groups: a candidate keyframe and its
// covisible keyframes (members include the candidate). A group continues a group of the previous
// update if they share at least one keyframe id; its count is then 1 + the largest count among the
// previous groups it continues, otherwise 1. Groups of the previous update that are not continued
// are dropped (an update with no candidates clears everything). A candidate is returned by every
// update in which its group's count is >= required: with required = 3, on the 3rd consecutive
// consistent update, and again on later ones while it stays consistent (so a failed geometric
// check can be retried on the next keyframe; call reset() after a loop is accepted).
// Note: ORB-SLAM2 starts counting at 0, so its threshold 3 corresponds to required = 4 here.
#include <vector>

#include "core/ids.h"

namespace cslam {

class ConsistencyChecker {
 public:
  // Throws ConfigError if required < 1.
  explicit ConsistencyChecker(int required = 3);

  struct Group {
    KeyFrameId candidate;
    std::vector<KeyFrameId> members;  // include the candidate (added if missing)
  };
  // Returns the candidates whose group is consistent (count >= required) at this update, each
  // once, in input order.
  std::vector<KeyFrameId> update(const std::vector<Group>& candidates);
  void reset();

  // State after the last update: one (members sorted, count) per candidate group, for inspection.
  struct Tracked {
    std::vector<KeyFrameId> members;
    int count = 0;
  };
  const std::vector<Tracked>& tracked() const { return groups_; }
  // Continues from a state read back from tracked() (a snapshot); members are sorted here.
  void restore(std::vector<Tracked> groups);
  int required() const { return required_; }

 private:
  int required_;
  std::vector<Tracked> groups_;
};

}  // namespace cslam
