#pragma once
// Keyframe database for place recognition: an inverted index word -> keyframes. Each database
// belongs to one client's map, but any BoW vector (from any client) can query it (map fusion).
// Thread-safe: add/erase/clear/query lock the database's own mutex; the query callbacks are
// called WITHOUT that lock held, so they may take map locks freely.
#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

#include "slam/bow/bow_vector.h"
#include "core/ids.h"

namespace cslam {

class KeyFrameDatabase {
 public:
  KeyFrameDatabase() = default;
  KeyFrameDatabase(const KeyFrameDatabase&) = delete;
  KeyFrameDatabase& operator=(const KeyFrameDatabase&) = delete;

  // Adds (or replaces) a keyframe's BoW vector.
  void add(KeyFrameId id, const BowVector& bow);
  void erase(KeyFrameId id);  // unknown id: no-op
  void clear();
  std::size_t size() const;
  bool contains(KeyFrameId id) const;

  struct Candidate {
    KeyFrameId id;
    double score = 0;
    double accumulated_score = 0;
    int common_words = 0;
  };
  struct QueryParams {
    double min_score = 0;  // loop/overlap detection: the lowest score between the keyframe and its covisible
                           // neighbours; 0 for relocalisation
    double min_common_words_ratio = 0.8;  // of the best candidate's common words
    double min_accumulated_ratio = 0.75;  // of the best group score
    std::size_t max_results = 0;          // 0 = no limit
  };

  // ORB-SLAM2 refinements: candidates sharing words (excluded ones dropped); keep those with
  // common words >= ratio * max; score >= min_score; accumulate each candidate's score over its
  // covisible neighbours (callback, may return empty) that passed the common-words test; return
  // the best keyframe of each group whose accumulated score >= ratio * best accumulated, sorted
  // by accumulated score desc (then score desc), each keyframe once. Callbacks may be empty.
  std::vector<Candidate> query(const BowVector& bow, const QueryParams& params,
                               const std::function<bool(KeyFrameId)>& exclude,
                               const std::function<std::vector<KeyFrameId>(KeyFrameId)>& covisible_neighbours) const;

  // Plain ranking by BoW score of every keyframe sharing a word (no groups), best first.
  std::vector<Candidate> rank(const BowVector& bow, std::size_t max_results = 0) const;

 private:
  struct Shared {
    int common_words = 0;
    std::shared_ptr<const BowVector> bow;
  };
  // Keyframes sharing at least one word with `bow`, with the count of shared words (under the lock).
  std::unordered_map<KeyFrameId, Shared> sharing_words(const BowVector& bow) const;

  mutable std::mutex mutex_;
  std::unordered_map<WordId, std::vector<KeyFrameId>> inverted_;
  std::unordered_map<KeyFrameId, std::shared_ptr<const BowVector>> bows_;
};

}  // namespace cslam
