// LiveDenseMap on hand-rendered keyframes of a fronto-parallel plane: submap windows, rigid moves
// that follow the keyframes' poses (no re-integration), re-integration when keyframes move
// relative to each other, culled keyframes, bounded pending images, mesh helpers.
#include <cmath>
#include <map>

#include <gtest/gtest.h>

#include "common/small_camera.h"
#include "dense/live_dense_map.h"
#include "dense/mesh_lod.h"

using namespace cslam;

namespace {

using test::small_camera;

DenseImages plane_images(const PinholeCamera& c, double depth_m) {
  return {test::plane_colour(c), test::plane_depth(c, depth_m)};
}

LiveDenseConfig small_config() {
  LiveDenseConfig c;
  c.tsdf.voxel_size = 0.02f;
  c.tsdf.truncation = 0.06f;
  c.keyframes_per_submap = 3;
  c.integration_delay_s = 0;
  c.mesh_interval_s = 0;
  return c;
}

KeyFrameId kf(ClientId client, std::uint32_t seq) { return KeyFrameId{client, seq}; }

// Keyframes of client 1 sliding sideways along x in front of the plane z = 1.
std::vector<KeyframePose> sliding_poses(int n, int group = 100) {
  std::vector<KeyframePose> poses;
  for (int i = 0; i < n; ++i)
    poses.push_back(
        {kf(1, std::uint32_t(i + 1)), group, 0, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.05 * i, 0, 0))});
  return poses;
}

SE3 correction() {
  return SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1, 0.1).normalized())),
             Eigen::Vector3d(1, -2, 0.5));
}

double pose_gap(const SE3& a, const SE3& b) {
  const SE3 d = a.inverse() * b;
  return d.translation().norm() + 2 * std::acos(std::min(1.0, std::abs(d.rotation().w())));
}

struct Fixture {
  PinholeCamera cam = small_camera();
  LiveDenseMap map{small_config()};
  int loads = 0;
  DenseImageLoader loader = [this](KeyFrameId) {
    ++loads;
    return std::optional<DenseImages>(plane_images(cam, 1.0));
  };
  Fixture() { map.set_camera(1, cam); }
  void add(int n) {
    for (int i = 0; i < n; ++i) map.add_keyframe(kf(1, std::uint32_t(i + 1)), plane_images(cam, 1.0), 0.0);
  }
};

}  // namespace

TEST(LiveDenseMap, WindowsOfKeyframesMeshOnTheSurface) {
  Fixture f;
  f.add(7);
  const auto r = f.map.flush(sliding_poses(7), f.loader);
  EXPECT_EQ(r.integrated, 7);
  EXPECT_EQ(f.loads, 0);  // the images at hand were used
  const auto view = f.map.view();
  ASSERT_EQ(view->submaps.size(), 3u);  // 3 + 3 + 1 keyframes
  EXPECT_EQ(view->submaps[0].keyframes.size(), 3u);
  EXPECT_EQ(view->submaps[2].keyframes.size(), 1u);
  for (const DenseSubmapView& s : view->submaps) {
    EXPECT_EQ(submap_client(s.id), 1);
    EXPECT_EQ(s.group, 100);
    ASSERT_TRUE(s.mesh);
    ASSERT_GT(s.mesh->triangles.size(), 100u);
    ASSERT_TRUE(s.nav_volume);
    for (const auto& v : s.mesh->vertices) EXPECT_NEAR((s.T_world_submap * v.cast<double>()).z(), 1.0, 0.01);
  }
}

TEST(LiveDenseMap, CorrectionMovesSubmapsRigidlyWithoutReintegration) {
  Fixture f;
  f.add(7);
  auto poses = sliding_poses(7);
  f.map.flush(poses, f.loader);
  const auto before = f.map.view();
  // A loop closure or fusion moves every keyframe by one rigid transform (and a new group).
  for (auto& p : poses) p.T_world_cam = correction() * p.T_world_cam, p.group = 300;
  const auto r = f.map.step(poses, 10.0, f.loader);
  EXPECT_EQ(r.moved, 3);
  EXPECT_EQ(r.reintegrated, 0);
  EXPECT_EQ(f.loads, 0);
  const auto after = f.map.view();
  EXPECT_GT(after->version, before->version);
  ASSERT_EQ(after->submaps.size(), before->submaps.size());
  std::map<KeyFrameId, SE3> current;
  for (const auto& p : poses) current[p.id] = p.T_world_cam;
  for (std::size_t i = 0; i < after->submaps.size(); ++i) {
    const DenseSubmapView &a = after->submaps[i], &b = before->submaps[i];
    EXPECT_EQ(a.version, b.version);  // geometry untouched
    EXPECT_EQ(a.pose_version, b.pose_version + 1);
    EXPECT_EQ(a.group, 300);
    EXPECT_LT(pose_gap(a.T_world_submap, correction() * b.T_world_submap), 1e-9);
    // The submap's frame is its first keyframe's camera frame, at that keyframe's current pose.
    EXPECT_LT(pose_gap(a.T_world_submap, current.at(a.keyframes.front())), 1e-9);
  }
}

TEST(LiveDenseMap, RelativeMotionBeyondThresholdReintegrates) {
  Fixture f;
  f.add(3);
  auto poses = sliding_poses(3);
  f.map.flush(poses, f.loader);
  const std::uint64_t version = f.map.view()->submaps.at(0).version;
  // 5 mm: below the 1 cm threshold, nothing rebuilt.
  poses[2].T_world_cam = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.005, 0, 0)) * poses[2].T_world_cam;
  auto r = f.map.step(poses, 10.0, f.loader);
  EXPECT_EQ(r.reintegrated, 0);
  EXPECT_NEAR(r.max_deviation_m, 0.005, 1e-9);
  // 5 cm more: the submap is rebuilt from the loader's images at the current poses.
  poses[2].T_world_cam = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.05, 0, 0)) * poses[2].T_world_cam;
  r = f.map.step(poses, 20.0, f.loader);
  EXPECT_EQ(r.reintegrated, 1);
  EXPECT_EQ(f.loads, 3);
  EXPECT_NEAR(r.max_deviation_m, 0.055, 1e-9);
  const DenseSubmapView& s = f.map.view()->submaps.at(0);
  EXPECT_GT(s.version, version);
  // Rebuilt: every keyframe now sits where its pose says.
  r = f.map.step(poses, 30.0, f.loader);
  EXPECT_EQ(r.reintegrated, 0);
  EXPECT_LT(r.max_deviation_m, 1e-9);
}

TEST(LiveDenseMap, NewKeyframesGoBeforeReintegration) {
  Fixture f;
  f.add(3);
  auto poses = sliding_poses(4);
  f.map.flush({poses.begin(), poses.begin() + 3}, f.loader);
  poses[1].T_world_cam = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.05, 0, 0)) * poses[1].T_world_cam;
  f.map.add_keyframe(kf(1, 4), plane_images(f.cam, 1.0), 0.0);
  // Keyframe 4 is due but over this step's budget: the distorted submap waits.
  auto r = f.map.step(poses, 10.0, f.loader, {0, 1});
  EXPECT_EQ(r.integrated, 0);
  EXPECT_EQ(r.reintegrated, 0);
  EXPECT_EQ(f.map.view()->distorted_submaps, 1u);  // readers see what the map still owes
  EXPECT_EQ(f.map.view()->keyframes_pending, 1u);
  // With room for it, the keyframe goes in first and the rebuild follows in the same step.
  r = f.map.step(poses, 20.0, f.loader, {1, 1});
  EXPECT_EQ(r.integrated, 1);
  EXPECT_EQ(r.reintegrated, 1);
  EXPECT_EQ(f.map.view()->distorted_submaps, 0u);
  EXPECT_EQ(f.map.view()->keyframes_pending, 0u);
}

TEST(LiveDenseMap, AnOpenSubmapsMeshLagsUntilItsIntervalAndTheViewSaysSo) {
  LiveDenseConfig config = small_config();
  config.mesh_interval_s = 3;
  LiveDenseMap map(config);
  const PinholeCamera cam = small_camera();
  map.set_camera(1, cam);
  const auto poses = sliding_poses(2);
  map.add_keyframe(kf(1, 1), plane_images(cam, 1.0), 0.0);
  map.step({poses[0]}, 10.0, {});
  const std::size_t vertices = map.view()->submaps.at(0).mesh->vertices.size();
  EXPECT_EQ(map.view()->stale_meshes, 0u);  // the first mesh is due at once
  // A second keyframe 1 s later: integrated, but its surface is not in the mesh until 3 s after the first.
  map.add_keyframe(kf(1, 2), plane_images(cam, 1.0), 11.0);
  map.step(poses, 11.0, {});
  EXPECT_EQ(map.view()->keyframes_integrated, 2u);
  EXPECT_EQ(map.view()->stale_meshes, 1u);
  EXPECT_EQ(map.view()->submaps.at(0).mesh->vertices.size(), vertices);
  map.step(poses, 12.5, {});
  EXPECT_EQ(map.view()->stale_meshes, 1u);
  map.step(poses, 13.0, {});
  EXPECT_EQ(map.view()->stale_meshes, 0u);
  EXPECT_GT(map.view()->submaps.at(0).mesh->vertices.size(), vertices);  // the slid view adds surface
}

TEST(LiveDenseMap, RotationCountsByTheDepthTheKeyframeSaw) {
  // The keyframes see the plane 1 m away: a rotation of a rad moves what they saw by a metres.
  Fixture f;
  f.add(3);
  auto poses = sliding_poses(3);
  f.map.flush(poses, f.loader);
  auto turn = [](double rad) {
    return SE3(Eigen::Quaterniond(Eigen::AngleAxisd(rad, Eigen::Vector3d::UnitY())), Eigen::Vector3d::Zero());
  };
  poses[1].T_world_cam = poses[1].T_world_cam * turn(0.008);  // 8 mm at 1 m: kept
  auto r = f.map.step(poses, 10.0, f.loader);
  EXPECT_EQ(r.reintegrated, 0);
  EXPECT_NEAR(r.max_deviation_m, 0.008, 1e-6);
  poses[1].T_world_cam = poses[1].T_world_cam * turn(0.006);  // 14 mm: rebuilt
  r = f.map.step(poses, 20.0, f.loader);
  EXPECT_EQ(r.reintegrated, 1);
  EXPECT_NEAR(r.max_deviation_m, 0.014, 1e-6);
}

TEST(LiveDenseMap, CulledKeyframesAreReportedAndEmptySubmapsRemoved) {
  Fixture f;
  f.add(4);
  auto poses = sliding_poses(4);
  f.map.flush(poses, f.loader);
  ASSERT_EQ(f.map.view()->submaps.size(), 2u);  // kf 1-3, kf 4
  // kf 2 culled: kf 3 and 4 are still listed, so it is gone for good.
  poses.erase(poses.begin() + 1);
  auto r = f.map.step(poses, 10.0, f.loader);
  ASSERT_EQ(r.culled.size(), 1u);
  EXPECT_EQ(r.culled[0], kf(1, 2));
  EXPECT_EQ(f.map.view()->submaps.at(0).keyframes.size(), 2u);
  // The newest keyframe missing is not culled (it may just not be listed yet)...
  poses.pop_back();
  r = f.map.step(poses, 11.0, f.loader);
  EXPECT_TRUE(r.culled.empty());
  // ... until a newer one of its client is listed.
  poses.push_back({kf(1, 5), 100, 0, SE3()});
  r = f.map.step(poses, 12.0, f.loader);
  ASSERT_EQ(r.culled.size(), 1u);
  EXPECT_EQ(r.culled[0], kf(1, 4));
  EXPECT_EQ(r.removed, 1);
  EXPECT_EQ(f.map.view()->submaps.size(), 1u);
}

TEST(LiveDenseMap, WaitsForPosesDelayAndCameraAndBoundsHeldImages) {
  LiveDenseConfig cfg = small_config();
  cfg.integration_delay_s = 1.0;
  cfg.max_pending_images = 2;
  LiveDenseMap map(cfg);
  const PinholeCamera cam = small_camera();
  int loads = 0;
  const DenseImageLoader loader = [&](KeyFrameId) {
    ++loads;
    return std::optional<DenseImages>(plane_images(cam, 1.0));
  };
  for (int i = 0; i < 5; ++i) map.add_keyframe(kf(1, std::uint32_t(i + 1)), plane_images(cam, 1.0), 0.0);
  const auto poses = sliding_poses(5);
  EXPECT_EQ(map.step(poses, 5.0, loader).integrated, 0);  // no camera yet
  map.set_camera(1, cam);
  EXPECT_EQ(map.step(poses, 0.5, loader).integrated, 0);  // too young for local BA to have refined
  const auto r = map.step(poses, 5.0, loader, {2, 0});    // budget: two per step
  EXPECT_EQ(r.integrated, 2);
  EXPECT_EQ(loads, 2);  // only the two newest kept their images
  EXPECT_EQ(map.step(poses, 6.0, loader).integrated, 3);
  EXPECT_EQ(loads, 3);
  EXPECT_EQ(map.pending(), 0u);
}

TEST(LiveDenseMap, BadImagesAreCountedNotFatal) {
  Fixture f;
  f.map.add_keyframe(kf(1, 1), DenseImages{cv::Mat(10, 10, CV_8UC3), cv::Mat(10, 10, CV_16UC1)}, 0.0);
  f.map.add_keyframe(kf(1, 2), DenseImages{}, 0.0);
  const DenseImageLoader none = [](KeyFrameId) { return std::optional<DenseImages>(); };
  const auto r = f.map.flush(sliding_poses(2), none);
  EXPECT_EQ(r.integrated, 0);
  EXPECT_EQ(r.missing_images, 2);
  EXPECT_TRUE(f.map.view()->submaps.empty());
}

TEST(MeshLod, ClusteringKeepsTheSurfaceWithFewerVertices) {
  Fixture f;
  f.add(3);
  f.map.flush(sliding_poses(3), f.loader);
  const TriangleMesh& mesh = *f.map.view()->submaps.at(0).mesh;
  const TriangleMesh coarse = simplify_by_clustering(mesh, 0.08f);
  EXPECT_LT(coarse.vertices.size() * 4, mesh.vertices.size());
  EXPECT_GT(coarse.triangles.size(), 10u);
  for (const auto& t : coarse.triangles)
    for (auto v : t) ASSERT_LT(v, coarse.vertices.size());
  for (const auto& v : coarse.vertices) EXPECT_NEAR(v.z(), 1.0, 0.01);
  // Two copies of one mesh placed 1 m apart merge into one; the cloud keeps one point per voxel.
  const SE3 shift(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 1));
  const TriangleMesh merged = merge_meshes({{&mesh, SE3()}, {&mesh, shift}});
  EXPECT_EQ(merged.vertices.size(), 2 * mesh.vertices.size());
  EXPECT_EQ(merged.triangles.size(), 2 * mesh.triangles.size());
  EXPECT_NEAR(merged.vertices[mesh.vertices.size()].z(), mesh.vertices[0].z() + 1, 1e-6);
  const ColoredCloud once = mesh_vertices_cloud({{&mesh, SE3()}}, 0.02f);
  const ColoredCloud twice = mesh_vertices_cloud({{&mesh, SE3()}, {&mesh, SE3()}}, 0.02f);
  EXPECT_EQ(once.size(), twice.size());
}
