#include "slam/bow/keyframe_database.h"

#include <algorithm>

#include "slam/bow/vocabulary.h"

namespace cslam {

void KeyFrameDatabase::add(KeyFrameId id, const BowVector& bow) {
  auto copy = std::make_shared<const BowVector>(bow);
  std::lock_guard<std::mutex> lock(mutex_);
  if (auto it = bows_.find(id); it != bows_.end()) {
    for (const auto& [w, v] : *it->second) {
      auto& list = inverted_[w];
      list.erase(std::remove(list.begin(), list.end(), id), list.end());
    }
  }
  for (const auto& [w, v] : *copy) inverted_[w].push_back(id);
  bows_[id] = std::move(copy);
}

void KeyFrameDatabase::erase(KeyFrameId id) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = bows_.find(id);
  if (it == bows_.end()) return;
  for (const auto& [w, v] : *it->second) {
    auto inv = inverted_.find(w);
    if (inv == inverted_.end()) continue;
    auto& list = inv->second;
    list.erase(std::remove(list.begin(), list.end(), id), list.end());
    if (list.empty()) inverted_.erase(inv);
  }
  bows_.erase(it);
}

void KeyFrameDatabase::clear() {
  std::lock_guard<std::mutex> lock(mutex_);
  inverted_.clear();
  bows_.clear();
}

std::size_t KeyFrameDatabase::size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return bows_.size();
}

bool KeyFrameDatabase::contains(KeyFrameId id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return bows_.count(id) > 0;
}

std::unordered_map<KeyFrameId, KeyFrameDatabase::Shared> KeyFrameDatabase::sharing_words(const BowVector& bow) const {
  std::unordered_map<KeyFrameId, Shared> out;
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& [w, v] : bow) {
    auto inv = inverted_.find(w);
    if (inv == inverted_.end()) continue;
    for (KeyFrameId id : inv->second) ++out[id].common_words;
  }
  for (auto& [id, s] : out) s.bow = bows_.at(id);
  return out;
}

std::vector<KeyFrameDatabase::Candidate> KeyFrameDatabase::query(
    const BowVector& bow, const QueryParams& params, const std::function<bool(KeyFrameId)>& exclude,
    const std::function<std::vector<KeyFrameId>(KeyFrameId)>& covisible_neighbours) const {
  std::unordered_map<KeyFrameId, Shared> shared = sharing_words(bow);  // lock released here
  if (exclude)
    for (auto it = shared.begin(); it != shared.end();) it = exclude(it->first) ? shared.erase(it) : std::next(it);
  if (shared.empty()) return {};

  int max_common = 0;
  for (const auto& [id, s] : shared) max_common = std::max(max_common, s.common_words);
  const double min_common = params.min_common_words_ratio * max_common;

  // Score the keyframes that share enough words; remember all of them for the group sums.
  std::unordered_map<KeyFrameId, double> scored;
  std::vector<Candidate> passing;
  for (const auto& [id, s] : shared) {
    if (s.common_words < min_common) continue;
    const double sc = Vocabulary::score(bow, *s.bow);
    scored[id] = sc;
    if (sc >= params.min_score) passing.push_back({id, sc, sc, s.common_words});
  }
  if (passing.empty()) return {};

  // Covisibility groups: each candidate's score plus its scored neighbours'; the group is
  // represented by its best-scoring keyframe.
  std::vector<Candidate> groups;
  double best_acc = 0;
  for (const Candidate& c : passing) {
    Candidate best = c;
    double acc = c.score;
    if (covisible_neighbours) {
      for (KeyFrameId n : covisible_neighbours(c.id)) {
        if (n == c.id) continue;
        auto it = scored.find(n);
        if (it == scored.end()) continue;
        acc += it->second;
        if (it->second > best.score) best = {n, it->second, 0, shared.at(n).common_words};
      }
    }
    best.accumulated_score = acc;
    best_acc = std::max(best_acc, acc);
    groups.push_back(best);
  }

  const double min_acc = params.min_accumulated_ratio * best_acc;
  std::sort(groups.begin(), groups.end(), [](const Candidate& a, const Candidate& b) {
    if (a.accumulated_score != b.accumulated_score) return a.accumulated_score > b.accumulated_score;
    if (a.score != b.score) return a.score > b.score;
    return a.id < b.id;
  });
  std::vector<Candidate> out;
  std::vector<KeyFrameId> seen;
  for (const Candidate& g : groups) {
    if (g.accumulated_score < min_acc) break;
    if (std::find(seen.begin(), seen.end(), g.id) != seen.end()) continue;
    seen.push_back(g.id);
    out.push_back(g);
    if (params.max_results > 0 && out.size() >= params.max_results) break;
  }
  return out;
}

std::vector<KeyFrameDatabase::Candidate> KeyFrameDatabase::rank(const BowVector& bow, std::size_t max_results) const {
  std::unordered_map<KeyFrameId, Shared> shared = sharing_words(bow);
  std::vector<Candidate> out;
  out.reserve(shared.size());
  for (const auto& [id, s] : shared) {
    const double sc = Vocabulary::score(bow, *s.bow);
    out.push_back({id, sc, sc, s.common_words});
  }
  std::sort(out.begin(), out.end(), [](const Candidate& a, const Candidate& b) {
    return a.score != b.score ? a.score > b.score : a.id < b.id;
  });
  if (max_results > 0 && out.size() > max_results) out.resize(max_results);
  return out;
}

}  // namespace cslam
