#include "navmap/octomap_export.h"

#include <iomanip>
#include <sstream>
#include <unordered_map>
#include <vector>

#include <octomap/OcTree.h>

#include "navmap/voxel_walk.h"

namespace cslam {

namespace {

struct LeafEvidence {
  int occupied = 0, free = 0;
};
using LeafMap = std::unordered_map<octomap::OcTreeKey, LeafEvidence, octomap::OcTreeKey::KeyHash>;

LeafMap submap_leaves(const SubmapView& view, const octomap::OcTree& tree, float min_weight, OctomapResult& out) {
  LeafMap leaves;
  octomap::OcTreeKey key;
  for_each_world_voxel(view, min_weight, [&](const Eigen::Vector3d& p, double d, const TsdfVoxel&) {
    if (!tree.coordToKeyChecked(p.x(), p.y(), p.z(), key)) {
      ++out.voxels_out_of_range;
      return;
    }
    LeafEvidence& e = leaves[key];
    (d <= 0 ? e.occupied : e.free) += 1;
  });
  return leaves;
}

}  // namespace

OctomapResult build_octomap(const SubmapViews& views, const NavMapConfig& c) {
  c.validate();
  OctomapResult out;
  octomap::OcTree tree(c.octomap_resolution);
  constexpr std::size_t kChunk = 8192;  // leaves updated between node-budget checks
  for (const SubmapView& v : views) {
    if (!usable(v)) {
      ++out.submaps_skipped;
      continue;
    }
    ++out.submaps_used;
    std::size_t done = 0;
    for (const auto& [key, e] : submap_leaves(v, tree, c.min_voxel_weight, out)) {
      if (e.occupied >= c.octomap_min_occupied_voxels)
        tree.updateNode(key, true, true);
      else if (e.free > 0)
        tree.updateNode(key, false, true);
      if (++done % kChunk == 0 && tree.size() > c.max_octree_nodes) break;
    }
    if (tree.size() > c.max_octree_nodes) {
      out.error = "octree beyond the budget of " + std::to_string(c.max_octree_nodes) + " nodes";
      return out;
    }
  }
  if (tree.size() == 0) return out;
  tree.updateInnerOccupancy();
  // What OcTree::writeBinary does (maximum likelihood, pruned, the .bt header, then the data),
  // without the " done." it prints on stderr.
  tree.toMaxLikelihood();
  tree.prune();
  std::ostringstream s(std::ios::binary);
  s << "# Octomap OcTree binary file\n# written by cslam navmap\n"  // the .bt magic line, then a comment
    << "id " << tree.getTreeType() << "\nsize " << tree.size() << "\nres " << std::setprecision(17)
    << tree.getResolution() << "\ndata\n";
  tree.writeBinaryData(s);
  if (!s.good()) {
    out.error = "octomap: writing the binary data failed";
    return out;
  }
  out.bt = s.str();
  out.nodes = tree.size();
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
    (tree.isNodeOccupied(*it) ? out.occupied_leaves : out.free_leaves) += 1;
  return out;
}

std::string to_octomap_bt(const SubmapViews& views, const NavMapConfig& config) {
  return build_octomap(views, config).bt;
}

}  // namespace cslam
