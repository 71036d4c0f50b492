#pragma once
// JSON form of a timing Summary (run statistics files).
#include <vector>

#include <nlohmann/json.hpp>

#include "core/stats.h"

namespace cslam {

inline nlohmann::json summary_json(const std::vector<double>& values) {
  const Summary s = summarize(values);
  return {{"n", s.n}, {"median", s.median}, {"mean", s.mean}, {"p95", s.p95}, {"min", s.min}, {"max", s.max}};
}

}  // namespace cslam
