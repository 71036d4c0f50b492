// Reclaiming an idle client's SLAM pipeline (CollaborativeSystem::retire_client, used by the
// server's --session-ttl): its threads are joined, its outputs written, the id may start anew.
#include <dirent.h>

#include <filesystem>
#include <thread>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/core/utility.hpp>

#include "common/process_threads.h"
#include "net_test_util.h"
#include "system/collaborative_system.h"

namespace cslam {
namespace {

using test::thread_count;

TEST(ReclaimPipeline, RetiredClientReleasesItsThreadsAndWritesItsOutputs) {
  const std::string out = test::scratch_dir("retire");
  SystemConfig sc;  // SLAM on: worker, local mapping and loop closing threads per client
  CollaborativeSystem system(sc);
  PinholeCamera cam;
  cam.name = "r";
  cam.width = 320;
  cam.height = 240;
  cam.fx = cam.fy = 260;
  cam.cx = 159.5;
  cam.cy = 119.5;
  cam.depth_factor = 5000;
  cv::parallel_for_(cv::Range(0, 4), [](const cv::Range&) {});  // OpenCV's pool exists before counting
  const std::size_t before = thread_count();
  system.add_client({1, "one", cam});
  const std::size_t with_client = thread_count();
  EXPECT_GE(with_client, before + 3) << "threads per client with SLAM: worker, local mapping, loop closing";
  cv::RNG rng(1);
  for (int i = 0; i < 5; ++i) {
    RgbdFrame f;
    f.client = 1;
    f.seq = std::uint64_t(i + 1);
    f.timestamp = i / 30.0;
    f.bgr = cv::Mat(240, 320, CV_8UC3);
    rng.fill(f.bgr, cv::RNG::UNIFORM, 0, 256);
    f.depth = cv::Mat(240, 320, CV_16UC1, cv::Scalar(6000));
    ASSERT_TRUE(system.submit(std::move(f)));
  }
  ASSERT_TRUE(system.retire_client(1, out + "/client_1-1"));  // drains its queue first
  EXPECT_FALSE(system.has_client(1));
  EXPECT_EQ(test::thread_count_settled_to(before), before);  // joined threads reaped
  EXPECT_TRUE(std::filesystem::exists(out + "/client_1-1/client_1.txt"));
  EXPECT_TRUE(std::filesystem::exists(out + "/client_1-1/stats.json"));
  EXPECT_TRUE(system.retire_client(1, out + "/again"));  // unknown: nothing to do
  // The id starts a new, empty pipeline.
  system.add_client({1, "one", cam});
  EXPECT_TRUE(system.has_client(1));
  const auto snap = system.snapshot();
  ASSERT_EQ(snap.clients.size(), 1u);
  EXPECT_EQ(snap.clients[0].frames_submitted, 0u);
  system.finish();
  EXPECT_FALSE(system.retire_client(1, out + "/late"));  // after finish: everything stays for the outputs
  std::filesystem::remove_all(out);
}

}  // namespace
}  // namespace cslam
