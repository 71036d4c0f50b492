#include "server/dense/dense_products.h"

#include <cstring>
#include <fstream>

#include "cloud/ply_io.h"
#include "dense/mesh_lod.h"
#include "navmap/map_server_io.h"

namespace cslam::server {

std::map<int, std::vector<const DenseSubmapView*>> submaps_by_group(const DenseMapView& view) {
  std::map<int, std::vector<const DenseSubmapView*>> out;
  for (const DenseSubmapView& s : view.submaps) out[s.group].push_back(&s);
  return out;
}

int largest_group(const DenseMapView& view) {
  int best = -1;
  std::size_t most = 0;
  for (const auto& [group, list] : submaps_by_group(view))
    if (list.size() > most) best = group, most = list.size();
  return best;
}

namespace {

std::vector<PlacedMesh> placed(const std::vector<const DenseSubmapView*>& submaps) {
  std::vector<PlacedMesh> out;
  for (const DenseSubmapView* s : submaps)
    if (s->mesh && !s->mesh->vertices.empty()) out.push_back({s->mesh.get(), s->T_world_submap});
  return out;
}

template <typename T>
void put(std::string& out, const T& v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  out.append(b, sizeof(T));
}

}  // namespace

TriangleMesh group_mesh(const std::vector<const DenseSubmapView*>& submaps) { return merge_meshes(placed(submaps)); }

ColoredCloud group_cloud(const std::vector<const DenseSubmapView*>& submaps) {
  const float voxel = submaps.empty() ? 0.01f : submaps.front()->voxel_size;
  return mesh_vertices_cloud(placed(submaps), voxel);
}

std::string encode_csm1(const TriangleMesh& mesh, std::uint32_t version) {
  const std::size_t nv = mesh.vertices.size(), nt = mesh.triangles.size();
  std::string out;
  out.reserve(16 + nv * 15 + 4 + nt * 12);
  out.append("CSM1", 4);
  put(out, version);
  put(out, std::uint32_t(nv));
  put(out, std::uint32_t(nt));
  for (const auto& v : mesh.vertices) out.append(reinterpret_cast<const char*>(v.data()), 12);
  const bool coloured = mesh.colors.size() == nv;
  for (std::size_t i = 0; i < nv; ++i) {
    const Rgb8 c = coloured ? mesh.colors[i] : Rgb8{200, 200, 200};
    out.append(reinterpret_cast<const char*>(c.data()), 3);
  }
  out.append((4 - (nv * 3) % 4) % 4, '\0');
  for (const auto& t : mesh.triangles) out.append(reinterpret_cast<const char*>(t.data()), 12);
  return out;
}

NavMaps group_nav_maps(const std::vector<const DenseSubmapView*>& submaps, const NavMapConfig& config) {
  SubmapViews views;
  std::vector<SE3> cameras;
  for (const DenseSubmapView* s : submaps) {
    if (s->nav_volume) views.push_back({s->nav_volume.get(), s->T_world_submap});
    cameras.push_back(s->T_world_submap);
  }
  return build_nav_maps(views, cameras, config);
}

std::vector<std::string> write_dense_outputs(const DenseMapView& view, const std::string& dir) {
  std::vector<std::string> written;
  for (const auto& [group, submaps] : submaps_by_group(view)) {
    const TriangleMesh mesh = group_mesh(submaps);
    if (mesh.triangles.empty()) continue;
    const std::string g = std::to_string(group);
    write_ply_mesh(dir + "/dense_mesh_" + g + ".ply", mesh);
    write_ply(dir + "/dense_cloud_" + g + ".ply", group_cloud(submaps));
    written.push_back(dir + "/dense_mesh_" + g + ".ply");
    written.push_back(dir + "/dense_cloud_" + g + ".ply");
    const NavMaps nav = group_nav_maps(submaps);
    if (!nav.grid.empty()) {
      const std::string stem = dir + "/occupancy_" + g;
      std::ofstream(stem + ".pgm", std::ios::binary) << to_pgm(nav.grid);
      std::ofstream(stem + ".yaml") << to_map_yaml(nav.grid, "occupancy_" + g + ".pgm");
      written.push_back(stem + ".pgm");
      written.push_back(stem + ".yaml");
    }
    if (!nav.octomap_bt.empty()) {
      std::ofstream(dir + "/octomap_" + g + ".bt", std::ios::binary) << nav.octomap_bt;
      written.push_back(dir + "/octomap_" + g + ".bt");
    }
  }
  return written;
}

}  // namespace cslam::server
