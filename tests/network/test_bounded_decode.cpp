// Case 2 (receiving thread blocked by a decompression bomb) and the decode pool: decoders stop
// at the size the header implies, and decoding happens on pool threads, one client at a time per
// client, so a client stuck in decoding never holds up another client's frames.
#include <poll.h>

#include <future>

#include <gtest/gtest.h>

#include "codec/image_codec.h"
#include "codec/png_guard.h"
#include "core/error.h"
#include "server/bench/hostile_payloads.h"
#include "net_test_util.h"
#include "server/decode_pool.h"

namespace cslam {
namespace {

const std::uint8_t* bytes(const std::string& s) { return reinterpret_cast<const std::uint8_t*>(s.data()); }

TEST(BoundedDecode, PngWhoseStreamInflatesPastItsHeaderIsCorrupt) {
  const std::string good = hostile::png_bomb(320, 240, 0);
  const cv::Mat ok = decode_rgb(RgbCodec::kPng, bytes(good), good.size(), 320, 240, "good");
  EXPECT_EQ(ok.cols, 320);
  // 64 MB of extra zeros behind a 320x240 header: about 64 kB on the wire.
  const std::string bomb = hostile::png_bomb(320, 240, 64u << 20);
  EXPECT_LT(bomb.size(), 200000u);
  try {
    decode_rgb(RgbCodec::kPng, bytes(bomb), bomb.size(), 320, 240, "bomb");
    FAIL() << "a PNG bomb was decoded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("inflates past"), std::string::npos) << e.what();
  }
  // The same for 16-bit depth PNGs.
  const std::string depth_bomb = hostile::png_bomb(64, 48, 8u << 20, true);
  EXPECT_THROW(decode_depth(DepthCodec::kPng, bytes(depth_bomb), depth_bomb.size(), 64, 48, "depth"), InputError);
  const std::string depth_ok = hostile::png_bomb(64, 48, 0, true);
  EXPECT_EQ(decode_depth(DepthCodec::kPng, bytes(depth_ok), depth_ok.size(), 64, 48, "depth").rows, 48);
}

TEST(BoundedDecode, PngStreamsThatStopShortOrCarryCompressedChunksAreRefused) {
  std::string png = hostile::png_bomb(32, 16, 0);
  // Truncate the image stream: fewer bytes than the header implies.
  EXPECT_THROW(check_png_stream(bytes(png), png.size() - 20, PngLimits{32, 16, false}, "cut"), InputError);
  // A zTXt chunk (compressed text, another bomb vector) before IEND.
  std::string with_ztxt = png.substr(0, png.size() - 12);
  hostile::put_chunk(with_ztxt, "zTXt", std::string("k\0\0xx", 5));
  hostile::put_chunk(with_ztxt, "IEND", "");
  EXPECT_THROW(check_png_stream(bytes(with_ztxt), with_ztxt.size(), PngLimits{32, 16, false}, "ztxt"), InputError);
  EXPECT_NO_THROW(check_png_stream(bytes(png), png.size(), PngLimits{32, 16, false}, "ok"));
  EXPECT_EQ(png_inflated_size(32, 16, 8, 2, false), 16u * (1 + 96));
}

TEST(BoundedDecode, JpegWithThousandsOfScansIsRefused) {
  cv::Mat img(48, 64, CV_8UC3, cv::Scalar(10, 20, 30));
  CodecOptions o;
  Bytes jpeg = encode_rgb(img, o);
  // Splice 200 empty scan headers (SOS segments) before EOI.
  std::string s(jpeg.begin(), jpeg.end() - 2);
  for (int i = 0; i < 200; ++i) s += std::string("\xff\xda\x00\x08\x01\x01\x00\x00\x3f\x00", 10);
  s += "\xff\xd9";
  EXPECT_THROW(decode_rgb(RgbCodec::kJpeg, bytes(s), s.size(), 64, 48, "scans"), InputError);
  EXPECT_EQ(decode_rgb(RgbCodec::kJpeg, jpeg.data(), jpeg.size(), 64, 48, "ok").cols, 64);
}

wire::RgbdFrame wire_frame(ClientId id, std::uint64_t seq, const PinholeCamera& cam) {
  return test::make_frame(id, seq, double(seq), cam).frame();
}

PinholeCamera camera() {
  PinholeCamera c;
  c.width = 64;
  c.height = 48;
  c.fx = c.fy = 50;
  c.cx = 31.5;
  c.cy = 23.5;
  return c;
}

TEST(DecodePool, AClientStuckInDecodingDoesNotHoldUpAnother) {
  std::promise<void> gate;
  std::shared_future<void> open = gate.get_future().share();
  std::promise<void> stuck;
  std::mutex m;
  std::vector<std::pair<ClientId, std::uint64_t>> submitted;
  server::DecodePool pool(2, 16, [&](RgbdFrame f) {
    if (f.client == 1 && f.seq == 1) {
      stuck.set_value();
      open.wait();  // client 1's first frame hangs (as a slow decode would)
    }
    std::lock_guard<std::mutex> lock(m);
    submitted.emplace_back(f.client, f.seq);
    return true;
  });
  const PinholeCamera cam = camera();
  auto post = [&](ClientId id, std::uint64_t seq) {
    server::DecodeJob j;
    j.client = id;
    j.seq = seq;
    j.camera = cam;
    j.source = "test";
    j.frame = std::make_unique<wire::RgbdFrame>(wire_frame(id, seq, cam));
    ASSERT_TRUE(pool.post(std::move(j)));
  };
  post(1, 1);
  stuck.get_future().wait();
  post(1, 2);  // must wait behind 1/1 (order per client)
  post(2, 1);
  post(2, 2);
  // Client 2's frames come through while client 1 is stuck.
  std::vector<server::DecodeResult> results;
  pollfd pfd{pool.read_fd(), POLLIN, 0};
  while (results.size() < 2) {
    ASSERT_GT(::poll(&pfd, 1, 20000), 0) << "client 2 was held up";
    for (auto& r : pool.drain()) results.push_back(std::move(r));
  }
  for (const auto& r : results) EXPECT_EQ(r.client, 2);
  gate.set_value();
  pool.finish();
  for (auto& r : pool.drain()) results.push_back(std::move(r));
  ASSERT_EQ(results.size(), 4u);
  std::vector<std::uint64_t> client1;
  for (const auto& [c, s] : submitted)
    if (c == 1) client1.push_back(s);
  EXPECT_EQ(client1, (std::vector<std::uint64_t>{1, 2}));
}

TEST(DecodePool, CorruptFrameIsARejectedResultAndTheQueueIsBounded) {
  server::DecodePool pool(1, 2, [](RgbdFrame) { return true; });
  const PinholeCamera cam = camera();
  server::DecodeJob j;
  j.client = 3;
  j.seq = 1;
  j.camera = cam;
  j.source = "client 3 frame 1";
  j.frame = std::make_unique<wire::RgbdFrame>(wire_frame(3, 1, cam));
  const std::string bomb = hostile::png_bomb(64, 48, 4u << 20);
  j.frame->mutable_rgb()->set_encoding(wire::RGB_PNG);
  j.frame->mutable_rgb()->set_data(bomb);
  ASSERT_TRUE(pool.post(std::move(j)));
  pool.finish();
  const auto results = pool.drain();
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].outcome, server::DecodeResult::Outcome::kRejected);
  EXPECT_EQ(results[0].code, wire::ERROR_CORRUPT_IMAGE);
  server::DecodeJob late;
  late.frame = std::make_unique<wire::RgbdFrame>();
  EXPECT_FALSE(pool.post(std::move(late)));  // finishing: refused, never blocks
}

// Over the wire: the bomb is refused as corrupt and another client is served meanwhile.
TEST(BoundedDecode, ServerRefusesABombAndKeepsServing) {
  server::ReceiverConfig rc;
  SystemConfig sc;
  sc.run_slam = false;
  test::InProcessServer srv(rc, sc);
  zmq::context_t ctx(1);
  PinholeCamera cam = camera();
  cam.width = 320;
  cam.height = 240;
  cam.cx = 160;
  cam.cy = 120;
  test::RawPeer hostile(ctx, srv.endpoint()), good(ctx, srv.endpoint());
  hostile.send(test::make_hello(1, cam));
  good.send(test::make_hello(2, cam));
  ASSERT_TRUE(hostile.receive(10000));
  ASSERT_TRUE(good.receive(10000));
  wire::ClientMessage m = test::make_frame(1, 1, 0.0, cam);
  m.mutable_frame()->mutable_rgb()->set_encoding(wire::RGB_PNG);
  m.mutable_frame()->mutable_rgb()->set_data(hostile::png_bomb(320, 240, 256u << 20));
  hostile.send(m);
  good.send(test::make_frame(2, 1, 0.0, cam));
  const auto ack = good.receive(20000);
  ASSERT_TRUE(ack && ack->has_ack());
  std::optional<wire::ServerMessage> e;
  for (int i = 0; i < 5 && !(e && e->has_error()); ++i) e = hostile.receive(20000);
  ASSERT_TRUE(e && e->has_error());
  EXPECT_EQ(e->error().code(), wire::ERROR_CORRUPT_IMAGE);
  EXPECT_EQ(e->error().credits(), 1u);
  srv.stop();
  EXPECT_EQ(srv.stats().clients().at(1).frames_accepted, 0u);
  EXPECT_EQ(srv.stats().clients().at(1).dropped.at("corrupt_image"), 1u);
}

}  // namespace
}  // namespace cslam
