// DenseService::wait_stored, which every map snapshot calls first: keyframes queued for the dense
// worker are in the keyframe store when it returns, even if the worker never ran (it runs at low
// priority and lags on a busy machine; a snapshot must not hold keyframes whose images are not
// stored yet).
#include <gtest/gtest.h>

#include "network/net_test_util.h"
#include "server/dense/dense_service.h"

namespace cslam::server {
namespace {

RgbdFrame grey_frame(const PinholeCamera& cam, double t) {
  RgbdFrame f;
  f.timestamp = t;
  f.bgr = cv::Mat(cam.height, cam.width, CV_8UC3, cv::Scalar(40, 80, 120));
  f.depth = cv::Mat(cam.height, cam.width, CV_16UC1, cv::Scalar(5000));
  return f;
}

TEST(DenseServiceStore, WaitStoredStoresWhatTheWorkerHasNotReached) {
  const test::ScratchDir dir("dense_wait_stored");
  SystemConfig sc;
  sc.run_slam = false;
  CollaborativeSystem system(sc);
  DenseServiceConfig config;
  config.store.dir = dir.path() + "/dense";
  DenseService dense(config, system);  // not started: no worker takes the queue
  const ClientInfo client{3, "robot3", test::small_camera()};
  EXPECT_TRUE(dense.wait_stored(0.1));  // nothing queued
  for (std::uint32_t seq = 1; seq <= 4; ++seq)
    dense.on_keyframe(client, KeyFrameId{3, seq}, grey_frame(client.camera, 1.0 + double(seq)), SE3());
  EXPECT_EQ(dense.stats().stored, 0u);
  EXPECT_TRUE(dense.wait_stored(5.0));
  const DenseServiceStats st = dense.stats();
  EXPECT_EQ(st.stored, 4u);
  EXPECT_EQ(st.encoded_here, 4u);  // no received bytes: stored as a lossless copy
  EXPECT_EQ(st.queue, 4u);         // still queued for the worker to integrate
  for (std::uint32_t seq = 1; seq <= 4; ++seq) {
    const auto stored = dense.stored_keyframe(KeyFrameId{3, seq});
    ASSERT_TRUE(stored) << "keyframe " << seq;
    EXPECT_EQ(stored->images.depth.at<std::uint16_t>(5, 5), 5000);
    EXPECT_EQ(stored->images.bgr.at<cv::Vec3b>(5, 5), cv::Vec3b(40, 80, 120));
  }
  EXPECT_TRUE(dense.wait_stored(0.1));  // stored once, not again
  EXPECT_EQ(dense.stats().stored, 4u);
}

}  // namespace
}  // namespace cslam::server
