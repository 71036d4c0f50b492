// The smallest robot program: links cslam_client_lib and nothing else. Its link line is what
// test_client_link_lean checks (no SLAM library, Ceres or OpenCV feature module), and building
// it proves the library links without them: every part a robot uses is referenced below.
#include <cstdio>

#include "client/frame_sender.h"
#include "proto/keys/curve_keys.h"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::printf("usage: %s ENDPOINT KEYFILE (links cslam_client_lib only; connects nowhere without arguments)\n",
                argv[0]);
    return 0;
  }
  cslam::client::SenderConfig config;
  config.server = argv[1];
  const cslam::auth::CurveKeyPair keys = cslam::auth::read_secret_file(argv[2]);
  config.public_key = keys.public_key;
  config.secret_key = keys.secret_key;
  cslam::client::FrameSender sender(config);
  sender.connect();
  cslam::RgbdFrame frame;
  frame.bgr = cv::Mat(config.info.camera.height, config.info.camera.width, CV_8UC3, cv::Scalar(0, 0, 0));
  frame.depth = cv::Mat(config.info.camera.height, config.info.camera.width, CV_16UC1, cv::Scalar(0));
  frame.seq = 1;
  sender.send_frame(frame);
  sender.offer_frame(frame);
  for (const cslam::wire::PoseFeedback& f : sender.take_poses()) std::printf("seq %llu\n", (unsigned long long)f.seq);
  sender.goodbye(1.0);
  return 0;
}
