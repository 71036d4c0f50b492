// The protobuf <-> library adapter: round trips and every kind of bad packet it must classify.
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "net_test_util.h"
#include "codec/video_codec.h"
#include "proto/adapter.h"

namespace cslam {
namespace {

PinholeCamera small_camera() {
  PinholeCamera c = camera_tum_fr1();
  c.width = 64;
  c.height = 48;
  return c;
}

wire::ErrorCode code_of(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const wire::WireError& e) {
    return e.code();
  }
  return wire::ERROR_UNSPECIFIED;
}

TEST(Adapter, HelloRoundTripKeepsCamera) {
  ClientInfo info;
  info.id = 42;
  info.name = "robot";
  info.camera = camera_tum_fr1();
  const ClientInfo back = wire::from_hello(wire::to_hello(info), "test");
  EXPECT_EQ(back.id, 42);
  EXPECT_EQ(back.name, "robot");
  EXPECT_EQ(back.camera.fx, info.camera.fx);
  EXPECT_EQ(back.camera.cy, info.camera.cy);
  EXPECT_EQ(back.camera.dist, info.camera.dist);
  EXPECT_EQ(back.camera.width, 640);
  EXPECT_EQ(back.camera.depth_factor, 5000.0);
  EXPECT_EQ(back.camera.readout_time, info.camera.readout_time);
  EXPECT_GT(back.camera.readout_time, 0.0);
  // A peer that does not send the readout time: a global-shutter camera.
  wire::Hello old = wire::to_hello(info);
  old.mutable_camera()->clear_readout_time();
  EXPECT_EQ(wire::from_hello(old, "test").camera.readout_time, 0.0);
}

TEST(Adapter, BadHellosAreClassified) {
  ClientInfo info;
  info.camera = small_camera();
  wire::Hello h = wire::to_hello(info);
  h.set_version(wire::PROTOCOL_VERSION_UNSPECIFIED);
  EXPECT_EQ(code_of([&] { wire::from_hello(h, "t"); }), wire::ERROR_BAD_VERSION);
  h = wire::to_hello(info);
  h.set_client_id(70000);
  EXPECT_EQ(code_of([&] { wire::from_hello(h, "t"); }), wire::ERROR_BAD_HELLO);
  h = wire::to_hello(info);
  h.mutable_camera()->set_fx(-1);
  EXPECT_EQ(code_of([&] { wire::from_hello(h, "t"); }), wire::ERROR_BAD_HELLO);
  h = wire::to_hello(info);
  h.mutable_camera()->set_width(100000);
  EXPECT_EQ(code_of([&] { wire::from_hello(h, "t"); }), wire::ERROR_BAD_HELLO);
  h = wire::to_hello(info);
  h.mutable_camera()->add_distortion(0.1);
  EXPECT_EQ(code_of([&] { wire::from_hello(h, "t"); }), wire::ERROR_BAD_HELLO);
  h = wire::to_hello(info);
  h.mutable_camera()->set_readout_time(-0.02);
  EXPECT_EQ(code_of([&] { wire::from_hello(h, "t"); }), wire::ERROR_BAD_HELLO);
  h = wire::to_hello(info);
  h.clear_camera();
  EXPECT_EQ(code_of([&] { wire::from_hello(h, "t"); }), wire::ERROR_BAD_HELLO);
}

class AdapterFrameTest : public ::testing::TestWithParam<std::pair<RgbCodec, DepthCodec>> {};

TEST_P(AdapterFrameTest, FrameRoundTrip) {
  const PinholeCamera cam = small_camera();
  CodecOptions o;
  o.rgb = GetParam().first;
  o.depth = GetParam().second;
  const wire::ClientMessage m = test::make_frame(3, 17, 12.5, cam, o);
  const RgbdFrame f = wire::from_wire_frame(m.frame(), cam, "test");
  EXPECT_EQ(f.client, 3);
  EXPECT_EQ(f.seq, 17u);
  EXPECT_EQ(f.timestamp, 12.5);
  EXPECT_EQ(f.bgr.cols, 64);
  EXPECT_EQ(f.depth.rows, 48);
  EXPECT_EQ(f.depth.at<std::uint16_t>(5, 5), 4000);  // lossless depth
}

INSTANTIATE_TEST_SUITE_P(Pairs, AdapterFrameTest,
                         ::testing::Values(std::pair{RgbCodec::kRaw, DepthCodec::kRaw},
                                           std::pair{RgbCodec::kJpeg, DepthCodec::kZstdDelta},
                                           std::pair{RgbCodec::kPng, DepthCodec::kPng},
                                           std::pair{RgbCodec::kJpeg, DepthCodec::kRvl}));

TEST(Adapter, UnknownEncodingIsClassified) {
  const PinholeCamera cam = small_camera();
  wire::ClientMessage m = test::make_frame(1, 1, 0, cam);
  m.mutable_frame()->mutable_rgb()->set_encoding(wire::Encoding(99));
  EXPECT_EQ(code_of([&] { wire::from_wire_frame(m.frame(), cam, "t"); }), wire::ERROR_UNKNOWN_ENCODING);
  m = test::make_frame(1, 1, 0, cam);
  m.mutable_frame()->mutable_depth()->set_encoding(wire::RGB_JPEG);  // an RGB encoding for depth
  EXPECT_EQ(code_of([&] { wire::from_wire_frame(m.frame(), cam, "t"); }), wire::ERROR_UNKNOWN_ENCODING);
}

TEST(Adapter, SizeContradictingTheHelloIsClassified) {
  const PinholeCamera cam = small_camera();
  wire::ClientMessage m = test::make_frame(1, 1, 0, cam);
  m.mutable_frame()->mutable_depth()->set_width(32);
  EXPECT_EQ(code_of([&] { wire::from_wire_frame(m.frame(), cam, "t"); }), wire::ERROR_SIZE_MISMATCH);
  PinholeCamera other = cam;
  other.width = 80;
  m = test::make_frame(1, 1, 0, other);  // consistent header, other size than the hello
  EXPECT_EQ(code_of([&] { wire::from_wire_frame(m.frame(), cam, "t"); }), wire::ERROR_SIZE_MISMATCH);
}

TEST(Adapter, DepthTimeOffsetRoundTripsAndImplausibleOffsetsAreMalformed) {
  const PinholeCamera cam = small_camera();
  wire::ClientMessage m = test::make_frame(1, 1, 0, cam);
  m.mutable_frame()->set_depth_time_offset(-0.0125);
  EXPECT_EQ(wire::from_wire_frame(m.frame(), cam, "t").depth_time_offset, -0.0125);
  // The C++ sender puts it on the wire.
  RgbdFrame f = wire::from_wire_frame(m.frame(), cam, "t");
  f.depth_time_offset = 0.016;
  wire::RgbdFrame out;
  ImageEncoder images{CodecOptions()};
  wire::to_wire_frame(f, images, &out);
  EXPECT_EQ(out.depth_time_offset(), 0.016);
  for (double bad : {0.5, -0.11, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    m.mutable_frame()->set_depth_time_offset(bad);
    EXPECT_EQ(code_of([&] { wire::check_frame(m.frame(), cam, "t"); }), wire::ERROR_MALFORMED) << bad;
    EXPECT_EQ(code_of([&] { wire::from_wire_frame(m.frame(), cam, "t"); }), wire::ERROR_MALFORMED) << bad;
  }
}

TEST(Adapter, CorruptImagesAreClassified) {
  const PinholeCamera cam = small_camera();
  CodecOptions png;
  png.rgb = RgbCodec::kPng;
  png.depth = DepthCodec::kPng;
  for (const CodecOptions& o : {CodecOptions(), png}) {
    wire::ClientMessage m = test::make_frame(1, 1, 0, cam, o);
    std::string bytes = m.frame().rgb().data();
    for (std::size_t i = 2; i < bytes.size(); i += 3) bytes[i] = char(0x5a);
    m.mutable_frame()->mutable_rgb()->set_data(bytes.substr(0, bytes.size() / 3));
    EXPECT_EQ(code_of([&] { wire::from_wire_frame(m.frame(), cam, "t"); }), wire::ERROR_CORRUPT_IMAGE);
    m = test::make_frame(1, 1, 0, cam, o);
    m.mutable_frame()->mutable_depth()->set_data("garbage");
    EXPECT_EQ(code_of([&] { wire::from_wire_frame(m.frame(), cam, "t"); }), wire::ERROR_CORRUPT_IMAGE);
  }
}

// Light frames: the colour stream's packets, decoded by the client's stream decoder, with
// subsampled depth spread back to full size, or none.
TEST(Adapter, LightFramesGoThroughTheClientsColourStream) {
  const PinholeCamera cam = small_camera();
  video::H264Encoder encoder(cam.width, cam.height, video::H264Options{});
  video::H264Decoder decoder(cam.width, cam.height);
  std::vector<wire::RgbdFrame> packets;
  for (int i = 0; i < 4; ++i) {
    RgbdFrame f;
    f.seq = std::uint64_t(i + 1);
    f.timestamp = 1.0 + i;
    f.bgr = cv::Mat(cam.height, cam.width, CV_8UC3, cv::Scalar(40 + 10 * i, 90, 160));
    f.depth = cv::Mat(cam.height, cam.width, CV_16UC1);
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x) f.depth.at<std::uint16_t>(y, x) = std::uint16_t(1000 + 7 * x + 3 * y);
    wire::RgbdFrame out;
    wire::to_wire_light_frame(f, encoder.encode(f.bgr, i == 0), i == 0 ? 4 : 0, CodecOptions(), &out);
    EXPECT_EQ(out.has_depth(), i == 0);
    EXPECT_EQ(out.rgb().encoding(), wire::RGB_H264);
    EXPECT_FALSE(wire::keyframe_eligible(out));
    packets.push_back(out);
  }
  // The first: depth at every 4th pixel of every 4th row (16 x 12), spread over its blocks.
  EXPECT_EQ(packets[0].depth().width(), 16u);
  EXPECT_EQ(packets[0].depth().height(), 12u);
  const RgbdFrame first = wire::from_wire_frame(packets[0], cam, "t", &decoder);
  EXPECT_EQ(first.depth_subsample, 4);
  EXPECT_FALSE(first.keyframe_eligible());
  ASSERT_EQ(first.depth.size(), cv::Size(cam.width, cam.height));
  EXPECT_EQ(first.depth.at<std::uint16_t>(0, 0), 1000);
  EXPECT_EQ(first.depth.at<std::uint16_t>(7, 6), std::uint16_t(1000 + 7 * 4 + 3 * 4));  // block (1, 1)'s sample
  EXPECT_EQ(first.depth.at<std::uint16_t>(47, 63), std::uint16_t(1000 + 7 * 60 + 3 * 44));
  EXPECT_EQ(first.bgr.size(), cv::Size(cam.width, cam.height));
  EXPECT_EQ(first.timestamp, 1.0);
  EXPECT_TRUE(wire::from_wire_frame(packets[1], cam, "t", &decoder).depth.empty());  // colour only
  // Subsampled depth of the wrong size, and a subsample beyond the limit.
  wire::RgbdFrame bad = packets[0];
  bad.mutable_depth()->set_width(17);
  EXPECT_EQ(code_of([&] { wire::check_frame(bad, cam, "t"); }), wire::ERROR_SIZE_MISMATCH);
  bad = packets[0];
  bad.set_depth_subsample(17);
  EXPECT_EQ(code_of([&] { wire::check_frame(bad, cam, "t"); }), wire::ERROR_MALFORMED);
  bad = packets[1];
  bad.set_depth_subsample(4);  // without a depth image
  EXPECT_EQ(code_of([&] { wire::check_frame(bad, cam, "t"); }), wire::ERROR_MALFORMED);
  // Without a stream decoder the path refuses inter-coded colour.
  EXPECT_EQ(code_of([&] { wire::from_wire_frame(packets[1], cam, "t"); }), wire::ERROR_UNKNOWN_ENCODING);
  // A lost packet (packets[2]): the next one lacks its reference, and so does every one until a key packet.
  EXPECT_EQ(code_of([&] { wire::from_wire_frame(packets[3], cam, "t", &decoder); }), wire::ERROR_STREAM_GAP);
  EXPECT_EQ(code_of([&] { wire::from_wire_frame(packets[2], cam, "t", &decoder); }), wire::ERROR_STREAM_GAP);
  // Full depth needs colour that decodes on its own.
  EXPECT_TRUE(wire::keyframe_eligible(test::make_frame(1, 1, 0, cam).frame()));
  wire::RgbdFrame h264_with_depth = test::make_frame(1, 1, 0, cam).frame();
  *h264_with_depth.mutable_rgb() = packets[0].rgb();
  EXPECT_EQ(code_of([&] { wire::check_frame(h264_with_depth, cam, "t"); }), wire::ERROR_MALFORMED);
  // A packet of another size than the camera's.
  wire::RgbdFrame wrong = packets[0];
  wrong.mutable_rgb()->set_width(32);
  EXPECT_EQ(code_of([&] { wire::check_frame(wrong, cam, "t"); }), wire::ERROR_SIZE_MISMATCH);
}

TEST(Adapter, RandomBytesAndTruncatedMessagesAreMalformed) {
  EXPECT_EQ(code_of([] { wire::parse_client_message("", 0, "t"); }), wire::ERROR_MALFORMED);  // no body
  const std::string junk = "\xff\xff\xff\xff\xff\xff\xff\xff\x01garbage";
  EXPECT_EQ(code_of([&] { wire::parse_client_message(junk.data(), junk.size(), "t"); }), wire::ERROR_MALFORMED);
  const std::string full = test::make_frame(1, 1, 0, small_camera()).SerializeAsString();
  EXPECT_EQ(code_of([&] { wire::parse_client_message(full.data(), full.size() / 2, "t"); }), wire::ERROR_MALFORMED);
  EXPECT_EQ(wire::parse_client_message(full.data(), full.size(), "t").body_case(), wire::ClientMessage::kFrame);
}

TEST(Adapter, ErrorsNameTheirSource) {
  try {
    wire::parse_client_message("x", 1, "client 7");
    FAIL() << "no exception";
  } catch (const wire::WireError& e) {
    EXPECT_NE(std::string(e.what()).find("client 7"), std::string::npos);
  }
}

}  // namespace
}  // namespace cslam
