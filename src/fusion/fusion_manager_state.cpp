// FusionManager's persistence hook (declared in fusion/fusion_manager.h).
#include "fusion/fusion_manager.h"

namespace cslam {

void FusionManager::restore_group(ClientId client, const std::shared_ptr<Map>& map, GroupId group) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  if (group_.count(map.get())) return;
  registry_.push_back({client, map});
  group_[map.get()] = group.valid() ? group : GroupId::of_map(client, map->index());
}

}  // namespace cslam
