#pragma once
// Locking several maps at once (fusion seams, group BA): always in address order, the one order
// every multi-map lock in cslam takes, so two such lockers can never deadlock.
#include <algorithm>
#include <shared_mutex>
#include <vector>

#include "slam/map/map.h"

namespace cslam {

template <class Lock>  // std::shared_lock<std::shared_mutex> or std::unique_lock<std::shared_mutex>
std::vector<Lock> lock_maps(std::vector<Map*> maps) {
  std::sort(maps.begin(), maps.end());
  maps.erase(std::unique(maps.begin(), maps.end()), maps.end());
  std::vector<Lock> locks;
  locks.reserve(maps.size());
  for (Map* m : maps) locks.emplace_back(m->mutex);
  return locks;
}

}  // namespace cslam
