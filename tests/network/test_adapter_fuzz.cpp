// Randomised test of the server's decode path: random and mutated protobuf messages through
// parse_client_message + from_wire_frame, thousands of times. Only WireError may come out.
#include <random>

#include <gtest/gtest.h>

#include "net_test_util.h"
#include "proto/adapter.h"

namespace cslam {
namespace {

TEST(AdapterFuzz, MutatedMessagesNeverCrashTheDecodePath) {
  PinholeCamera cam = camera_tum_fr1();
  cam.width = 64;  // the smallest plausible camera is 48x48 (PinholeCamera::validate)
  cam.height = 48;
  cam.fx = cam.fy = 50;
  cam.cx = 31.5;
  cam.cy = 23.5;
  std::mt19937 rng(99);
  std::vector<std::string> seeds;
  CodecOptions png;
  png.rgb = RgbCodec::kPng;
  png.depth = DepthCodec::kPng;
  CodecOptions rvl;
  rvl.depth = DepthCodec::kRvl;
  for (const CodecOptions& o : {CodecOptions(), png, rvl})
    seeds.push_back(test::make_frame(1, 1, 0, cam, o).SerializeAsString());
  seeds.push_back(test::make_hello(1, cam).SerializeAsString());
  int parsed = 0, decoded = 0, rejected = 0;
  const int kIterations = 5000;
  for (int i = 0; i < kIterations; ++i) {
    std::string bytes = seeds[std::size_t(i) % seeds.size()];
    switch (rng() % 4) {
      case 0:
        for (int k = 0; k < 1 + int(rng() % 6); ++k) bytes[rng() % bytes.size()] = char(rng());
        break;
      case 1:
        bytes.resize(rng() % bytes.size());
        break;
      case 2:
        bytes.assign(rng() % 300, '\0');
        for (auto& c : bytes) c = char(rng());
        break;
      default:
        bytes.insert(rng() % bytes.size(), std::string(1 + rng() % 20, char(rng())));
        break;
    }
    try {
      const wire::ClientMessage m = wire::parse_client_message(bytes.data(), bytes.size(), "fuzz");
      ++parsed;
      if (m.has_frame()) {
        const RgbdFrame f = wire::from_wire_frame(m.frame(), cam, "fuzz");
        EXPECT_EQ(f.bgr.cols, 64);
        EXPECT_EQ(f.depth.rows, 48);
        ++decoded;
      } else if (m.has_hello()) {
        wire::from_hello(m.hello(), "fuzz");
      }
    } catch (const wire::WireError&) {
      ++rejected;
    }
  }
  EXPECT_GT(rejected, kIterations / 4);
  EXPECT_GT(parsed, 0);
  EXPECT_GE(decoded, 0);
}

}  // namespace
}  // namespace cslam
