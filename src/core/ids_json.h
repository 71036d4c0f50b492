#pragma once
// JSON spelling of the ids (nlohmann::json finds these by argument-dependent lookup): a group is
// its number in every status page, stats file and API reply.
#include <nlohmann/json.hpp>

#include "core/ids.h"

namespace cslam {

inline void to_json(nlohmann::json& j, GroupId g) { j = g.value(); }
inline void from_json(const nlohmann::json& j, GroupId& g) { g = GroupId::from_value(j.get<int>()); }

}  // namespace cslam
