// Reconstruction jobs of the HTTP server (docs/security.md, items 5 and 6 of hardening round 2):
// finished jobs expire by count and age with their threads joined and bytes accounted; a
// request's memory is estimated before it starts and refused over the budget; a job that grows
// the process past the budget while it runs stops.
#include <dirent.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "common/process_threads.h"
#include "common/run_program.h"
#include "server/http/recon_jobs.h"

namespace cslam::http {
namespace {

namespace fs = std::filesystem;

PinholeCamera camera(int w = 64, int h = 48) {
  PinholeCamera c;
  c.width = w;
  c.height = h;
  c.fx = c.fy = 0.8 * w;
  c.cx = (w - 1) / 2.0;
  c.cy = (h - 1) / 2.0;
  return c;
}

// A TUM-layout folder of `frames` frames (a textured plane 1 m ahead) and their poses.
DatasetPoses tiny_dataset(const std::string& dir, int frames) {
  fs::remove_all(dir);
  fs::create_directories(dir + "/rgb");
  fs::create_directories(dir + "/depth");
  const PinholeCamera cam = camera();
  std::ofstream rgb(dir + "/rgb.txt"), depth(dir + "/depth.txt");
  DatasetPoses out{dir, {}, cam};
  for (int i = 0; i < frames; ++i) {
    const double t = 1.0 + 0.1 * i;
    const std::string name = std::to_string(i) + ".png";
    cv::Mat bgr(cam.height, cam.width, CV_8UC3);
    cv::randu(bgr, 0, 255);
    cv::imwrite(dir + "/rgb/" + name, bgr);
    cv::imwrite(dir + "/depth/" + name, cv::Mat(cam.height, cam.width, CV_16UC1, cv::Scalar(5000)));
    rgb << t << " rgb/" << name << "\n";
    depth << t << " depth/" << name << "\n";
    out.poses.push_back({t, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.01 * i, 0, 0))});
  }
  return out;
}

DenseConfig server_defaults(double voxel = 0.02, int stride = 4, bool mesh = true) {
  DenseConfig dc;  // as POST /api/reconstruction sets it
  dc.voxel_size = voxel;
  dc.stride = stride;
  dc.build_mesh = mesh;
  dc.tsdf.voxel_size = float(voxel);
  dc.tsdf.truncation = float(4 * voxel);
  dc.threads = 1;
  dc.tsdf.threads = 1;
  return dc;
}

using test::thread_count;

// Waits (generously, no timing assert) until the job has finished.
ReconJobView wait_finished(const ReconJobs& jobs, const std::string& id) {
  for (int i = 0; i < 6000; ++i) {
    const auto v = jobs.view(id);
    if (!v) return {};
    if (v->state != "queued" && v->state != "running") return *v;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ADD_FAILURE() << "job " << id << " did not finish";
  return {};
}

// This process's own folder (two suites may run at once), removed at exit.
const test::TempDir kTemp("cslam_recon_jobs_test");
const std::string kDir = kTemp.str();

// Item 5: jobs beyond max_finished are dropped oldest first, their threads joined, and the bytes
// the kept ones hold are shown per job and in stats().
TEST(ReconJobs, FinishedJobsExpireByCountWithThreadsJoinedAndBytesAccounted) {
  const DatasetPoses data = tiny_dataset(kDir + "/count", 6);
  ReconJobsConfig config;
  config.max_finished = 2;
  ReconJobs jobs(config);
  const std::size_t threads_before = thread_count();
  std::vector<std::string> ids;
  for (int i = 0; i < 5; ++i) {
    const ReconStart s = jobs.start(0, {data}, server_defaults());
    ASSERT_EQ(s.outcome, ReconStart::Outcome::kStarted) << s.message;
    ids.push_back(s.id);
    const ReconJobView v = wait_finished(jobs, s.id);
    EXPECT_EQ(v.state, "done") << v.message;
    EXPECT_GT(v.bytes_held, 0u);
    EXPECT_GT(v.estimate_mb, 0.0);
  }
  jobs.expire();
  const ReconStats st = jobs.stats();
  EXPECT_EQ(st.jobs, 2u);
  EXPECT_EQ(st.expired, 3u);
  EXPECT_EQ(st.started, 5u);
  EXPECT_FALSE(jobs.view(ids[0]));  // the oldest went first
  EXPECT_FALSE(jobs.cloud_ply(ids[2]));
  ASSERT_TRUE(jobs.view(ids[4]));
  EXPECT_EQ(st.bytes_held, jobs.view(ids[3])->bytes_held + jobs.view(ids[4])->bytes_held);
  EXPECT_LE(test::thread_count_settled_to(threads_before), threads_before);  // every finished job's thread joined
}

// The products go to memory, never through a temp file: a server whose TMPDIR cannot be written
// (a read-only container root) still answers reconstructions.
TEST(ReconJobs, ProductsNeedNoTempFolder) {
  const DatasetPoses data = tiny_dataset(kDir + "/notmp", 6);
  const char* before = std::getenv("TMPDIR");
  const std::string saved = before ? before : "";
  ::setenv("TMPDIR", (kDir + "/no-such-folder").c_str(), 1);
  ReconJobs jobs(ReconJobsConfig{});
  const ReconStart s = jobs.start(0, {data}, server_defaults());
  const ReconJobView v = s.outcome == ReconStart::Outcome::kStarted ? wait_finished(jobs, s.id) : ReconJobView{};
  if (before)
    ::setenv("TMPDIR", saved.c_str(), 1);
  else
    ::unsetenv("TMPDIR");
  ASSERT_EQ(s.outcome, ReconStart::Outcome::kStarted) << s.message;
  EXPECT_EQ(v.state, "done") << v.message;
  const auto cloud = jobs.cloud_ply(s.id);
  ASSERT_TRUE(cloud);
  EXPECT_EQ(cloud->rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
}

TEST(ReconJobs, FinishedJobsExpireByAge) {
  const DatasetPoses data = tiny_dataset(kDir + "/age", 4);
  ReconJobsConfig config;
  config.max_age_s = 0;  // finished jobs go at the next expire()
  ReconJobs jobs(config);
  const ReconStart s = jobs.start(0, {data}, server_defaults());
  ASSERT_EQ(s.outcome, ReconStart::Outcome::kStarted) << s.message;
  wait_finished(jobs, s.id);
  jobs.expire();
  EXPECT_FALSE(jobs.view(s.id));
  EXPECT_EQ(jobs.stats().bytes_held, 0u);
  EXPECT_EQ(jobs.stats().expired, 1u);
  // And by the bytes they hold together: over the cap, the oldest go until it fits.
  ReconJobsConfig small;
  small.max_held_mb = 1e-9;
  ReconJobs capped(small);
  const ReconStart c = capped.start(0, {data}, server_defaults());
  ASSERT_EQ(c.outcome, ReconStart::Outcome::kStarted) << c.message;
  EXPECT_GT(wait_finished(capped, c.id).bytes_held, 0u);
  capped.expire();
  EXPECT_EQ(capped.stats().bytes_held, 0u);
  EXPECT_EQ(capped.stats().jobs, 0u);
}

// Item 6: the finest request on the scene of the probe (2 x 60 frames, 320x240) is estimated
// beyond a gigabyte and refused with the estimate; the server's default request fits easily.
TEST(ReconJobs, FinestRequestIsEstimatedAndRefusedOverTheBudget) {
  // Two robots, 60 frames each of a wall 2 m ahead, moving 3 cm per frame (depth images only:
  // the estimate reads a sample of them; the colour images are never read).
  std::vector<DatasetPoses> scene;
  for (int robot = 0; robot < 2; ++robot) {
    const std::string dir = kDir + "/scene" + std::to_string(robot);
    fs::remove_all(dir);
    fs::create_directories(dir + "/depth");
    DatasetPoses d{dir, {}, camera(320, 240)};
    d.camera.fx = d.camera.fy = 258.5;  // the synthetic 320x240 camera
    std::ofstream rgb(dir + "/rgb.txt"), depth(dir + "/depth.txt");
    const cv::Mat wall(240, 320, CV_16UC1, cv::Scalar(10000));  // 2 m
    for (int i = 0; i < 60; ++i) {
      const double t = 0.1 * i;
      const std::string name = std::to_string(i) + ".png";
      cv::imwrite(dir + "/depth/" + name, wall);
      rgb << t << " rgb/" << name << "\n";
      depth << t << " depth/" << name << "\n";
      d.poses.push_back({t, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.03 * i, 0.5 * robot, 0))});
    }
    scene.push_back(d);
  }
  const ReconEstimate finest = estimate_recon_memory(scene, server_defaults(0.002, 1, true));
  const ReconEstimate fine_cloud = estimate_recon_memory(scene, server_defaults(0.002, 1, false));
  const ReconEstimate defaults = estimate_recon_memory(scene, server_defaults());
  EXPECT_EQ(finest.frames, 120u);
  EXPECT_GT(finest.surface_m2, 7.0);  // the wall seen: 4.2 x 1.9 m (10 cm cells count a little high)
  EXPECT_LT(finest.surface_m2, 15.0);
  EXPECT_GT(finest.total_mb(), 1024.0) << finest.summary();
  EXPECT_LT(defaults.total_mb(), 100.0) << defaults.summary();
  EXPECT_LT(fine_cloud.total_mb(), finest.total_mb());
  ReconJobs jobs;  // default budget
  const ReconStart refused = jobs.start(0, scene, server_defaults(0.002, 1, true));
  EXPECT_EQ(refused.outcome, ReconStart::Outcome::kOverBudget);
  EXPECT_NE(refused.message.find("over the 768 MB budget (--recon-max-mb)"), std::string::npos) << refused.message;
  EXPECT_NE(refused.message.find("TSDF"), std::string::npos) << refused.message;
  EXPECT_EQ(jobs.stats().refused_over_budget, 1u);
  EXPECT_EQ(jobs.stats().jobs, 0u);
}

// Item 6, while running: a job that grows the process past the budget stops cleanly.
TEST(ReconJobs, JobThatGrowsPastTheBudgetWhileRunningStops) {
  const DatasetPoses data = tiny_dataset(kDir + "/grow", 6);
  std::atomic<std::size_t> calls{0};
  ReconJobsConfig config;
  config.max_mb = 100;
  config.memory_probe = [&calls] { return calls++ == 0 ? std::size_t(200) << 20 : std::size_t(500) << 20; };  // +300 MB
  ReconJobs jobs(config);
  const ReconStart s = jobs.start(0, {data}, server_defaults());
  ASSERT_EQ(s.outcome, ReconStart::Outcome::kStarted) << s.message;
  const ReconJobView v = wait_finished(jobs, s.id);
  EXPECT_EQ(v.state, "failed");
  EXPECT_NE(v.message.find("over the 100 MB budget"), std::string::npos) << v.message;
  EXPECT_EQ(v.bytes_held, 0u);
  EXPECT_EQ(jobs.stats().stopped_over_budget, 1u);
  // The stopped job holds no slot: the next request starts.
  EXPECT_EQ(jobs.start(0, {data}, server_defaults()).outcome, ReconStart::Outcome::kStarted);
}

}  // namespace
}  // namespace cslam::http
