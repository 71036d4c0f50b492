// cslam-recon and cslam-eval cloud end to end on a tiny hand-made dataset: a valid PLY/mesh is
// written and measures ~0 against itself; an empty result exits 1 and writes nothing.
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "cloud/ply_io.h"
#include "geometry/camera_io.h"

using namespace cslam;
namespace fs = std::filesystem;

namespace {

struct TinyDataset {
  fs::path root;
  TinyDataset() : root(fs::temp_directory_path() / ("cslam_recon_cli_" + std::to_string(::getpid()))) {
    fs::remove_all(root);
    fs::create_directories(root / "rgb");
    fs::create_directories(root / "depth");
    PinholeCamera c;
    c.fx = c.fy = 60;
    c.cx = 39.5;
    c.cy = 29.5;
    c.width = 80;
    c.height = 60;
    save_camera_file(c, (root / "camera.yaml").string());
    std::ofstream rgb(root / "rgb.txt"), depth(root / "depth.txt"), poses(root / "poses.txt"), none(root / "none.txt");
    for (int i = 0; i < 6; ++i) {
      const std::string name = std::to_string(i) + ".png";
      cv::imwrite((root / "rgb" / name).string(), cv::Mat(60, 80, CV_8UC3, cv::Scalar(200, 100, 50)));
      // A plane at 1 m with a box 20 cm nearer in the middle.
      cv::Mat d(60, 80, CV_16UC1, cv::Scalar(5000));
      d(cv::Rect(30, 20, 20, 20)).setTo(4000);
      cv::imwrite((root / "depth" / name).string(), d);
      rgb << 1.0 + 0.1 * i << " rgb/" << name << "\n";
      depth << 1.0 + 0.1 * i << " depth/" << name << "\n";
      poses << 1.0 + 0.1 * i << " " << 0.02 * i << " 0 0 0 0 0 1\n";
    }
    none << "50.0 0 0 0 0 0 0 1\n";
  }
  ~TinyDataset() { fs::remove_all(root); }
  std::string p(const std::string& name) const { return (root / name).string(); }
};

int run(const std::string& cmd) { return std::system((cmd + " > /dev/null 2>&1").c_str()); }

}  // namespace

TEST(ReconCli, WritesCloudAndMeshAndEvaluates) {
  TinyDataset ds;
  const std::string bin = CSLAM_BIN_DIR;
  ASSERT_EQ(run(bin + "/cslam-recon --dataset " + ds.root.string() + " --poses " + ds.p("poses.txt") +
                " --stride 1 --out " + ds.p("c.ply") + " --pcd " + ds.p("c.pcd") + " --mesh " + ds.p("m.ply")),
            0);
  const ColoredCloud c = read_ply(ds.p("c.ply"));
  ASSERT_GT(c.size(), 1000u);
  EXPECT_EQ(c.colors[0], (Rgb8{50, 100, 200}));
  for (const auto& q : c.points)
    EXPECT_TRUE(std::abs(q.z() - 1.0f) < 1e-3f || std::abs(q.z() - 0.8f) < 1e-3f) << q.transpose();
  EXPECT_TRUE(fs::exists(ds.p("c.pcd")));
  EXPECT_GT(read_ply_mesh(ds.p("m.ply")).triangles.size(), 100u);
  const std::string eval =
      bin + "/cslam-eval cloud " + ds.p("c.ply") + " " + ds.p("c.ply") + " --match-bbox --json > " + ds.p("e.json");
  ASSERT_EQ(std::system(eval.c_str()), 0);
  std::ifstream f(ds.p("e.json"));
  const nlohmann::json j = nlohmann::json::parse(f);
  EXPECT_LT(j["hausdorff"]["symmetric"].get<double>(), 1e-6);
  EXPECT_EQ(j["ref_points"].get<int>(), int(c.size()));
  EXPECT_NEAR(j["bbox"]["scale"].get<double>(), 1.0, 1e-9);
}

TEST(ReconCli, EmptyResultFailsAndWritesNothing) {
  TinyDataset ds;
  const std::string bin = CSLAM_BIN_DIR;
  EXPECT_NE(run(bin + "/cslam-recon --dataset " + ds.root.string() + " --poses " + ds.p("none.txt") + " --out " +
                ds.p("x.ply")),
            0);
  EXPECT_FALSE(fs::exists(ds.p("x.ply")));
  EXPECT_NE(run(bin + "/cslam-recon --dataset " + ds.root.string() + " --poses " + ds.p("poses.txt") + " --out " +
                ds.p("x.txt")),
            0);
  EXPECT_NE(run(bin + "/cslam-eval cloud " + ds.p("missing.ply") + " " + ds.p("missing.ply")), 0);
  EXPECT_EQ(run(bin + "/cslam-recon --help"), 0);
}

// cslam-dense-replay: the live dense map rebuilt from keyframe trajectories (two clients here)
// through the server's LiveDenseMap: its cloud lies on the plane (1 m) and the box (0.8 m).
TEST(DenseReplayCli, RebuildsTheLiveMapFromKeyframes) {
  TinyDataset ds;
  const std::string bin = CSLAM_BIN_DIR;
  {
    std::ifstream in(ds.p("poses.txt"));
    std::ofstream a(ds.p("kf_1.txt")), b(ds.p("kf_2.txt"));
    std::string line;
    for (int i = 0; std::getline(in, line); ++i) (i < 3 ? a : b) << line << "\n";
  }
  ASSERT_EQ(
      run(bin + "/cslam-dense-replay --dataset " + ds.root.string() + " --keyframes " + ds.p("kf_1.txt") + " " +
          ds.p("kf_2.txt") + " --voxel 0.01 --submap-keyframes 2 --out " + ds.p("r.ply") + " --mesh " + ds.p("rm.ply")),
      0);
  const ColoredCloud c = read_ply(ds.p("r.ply"));
  ASSERT_GT(c.size(), 100u);
  int on_surface = 0;
  for (const auto& q : c.points) on_surface += std::abs(q.z() - 1.0f) < 0.006f || std::abs(q.z() - 0.8f) < 0.006f;
  EXPECT_GT(on_surface, int(0.95 * double(c.size())));
  EXPECT_GT(read_ply_mesh(ds.p("rm.ply")).triangles.size(), 100u);
  // A missing trajectory file is a clear error, not an empty map.
  EXPECT_NE(run(bin + "/cslam-dense-replay --dataset " + ds.root.string() + " --keyframes " + ds.p("missing.txt") +
                " --out " + ds.p("x.ply")),
            0);
}
