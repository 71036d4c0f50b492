#include "slam/loop/consistency.h"

#include <algorithm>

#include "core/error.h"

namespace cslam {

namespace {

bool share_any(const std::vector<KeyFrameId>& a, const std::vector<KeyFrameId>& b) {  // both sorted
  auto i = a.begin();
  auto j = b.begin();
  while (i != a.end() && j != b.end()) {
    if (*i == *j) return true;
    if (*i < *j)
      ++i;
    else
      ++j;
  }
  return false;
}

}  // namespace

ConsistencyChecker::ConsistencyChecker(int required) : required_(required) {
  if (required < 1) throw ConfigError("ConsistencyChecker: required must be >= 1");
}

void ConsistencyChecker::reset() { groups_.clear(); }

void ConsistencyChecker::restore(std::vector<Tracked> groups) {
  for (auto& g : groups) std::sort(g.members.begin(), g.members.end());
  groups_ = std::move(groups);
}

std::vector<KeyFrameId> ConsistencyChecker::update(const std::vector<Group>& candidates) {
  std::vector<Tracked> next;
  next.reserve(candidates.size());
  std::vector<KeyFrameId> out;
  for (const auto& c : candidates) {
    Tracked t;
    t.members = c.members;
    t.members.push_back(c.candidate);
    std::sort(t.members.begin(), t.members.end());
    t.members.erase(std::unique(t.members.begin(), t.members.end()), t.members.end());
    int best_previous = 0;
    for (const auto& g : groups_)
      if (g.count > best_previous && share_any(t.members, g.members)) best_previous = g.count;
    t.count = best_previous + 1;
    if (t.count >= required_ && std::find(out.begin(), out.end(), c.candidate) == out.end()) out.push_back(c.candidate);
    next.push_back(std::move(t));
  }
  groups_ = std::move(next);
  return out;
}

}  // namespace cslam
