// H.264 colour stream (codec/video_codec.h): round trip, key frames, determinism, and the
// decoder's chain rule under loss, reordering, duplication and corruption. Synthetic fixtures: a
// textured image seen through a window that moves a few pixels per frame.
#include <cmath>
#include <cstring>
#include <random>
#include <set>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>
#include <zlib.h>

#include "codec/video_codec.h"
#include "core/error.h"

namespace cslam::video {
namespace {

constexpr int kW = 160, kH = 120;

// Blurred grey noise (luma detail, as in a camera image) over smooth colour gradients, with
// coloured shapes; large enough for a window to pan over it. (Colour noise would measure only
// the 4:2:0 chroma subsampling that JPEG and H.264 share.)
const cv::Mat& texture() {
  static const cv::Mat tex = [] {
    const int w = kW + 300, h = kH + 200;
    cv::Mat grey(h, w, CV_8UC1);
    cv::RNG rng(7);
    rng.fill(grey, cv::RNG::UNIFORM, 0, 256);
    cv::GaussianBlur(grey, grey, cv::Size(7, 7), 1.5);
    cv::Mat im(h, w, CV_8UC3);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const int g = grey.at<std::uint8_t>(y, x) - 128;
        im.at<cv::Vec3b>(y, x) =
            cv::Vec3b(cv::saturate_cast<std::uint8_t>(60 + 120 * x / w + g), cv::saturate_cast<std::uint8_t>(128 + g),
                      cv::saturate_cast<std::uint8_t>(190 - 120 * y / h + g));
      }
    for (int i = 0; i < 40; ++i) {
      const cv::Point c(rng.uniform(0, w), rng.uniform(0, h));
      const cv::Scalar colour(rng.uniform(0, 256), rng.uniform(0, 256), rng.uniform(0, 256));
      if (i % 2)
        cv::circle(im, c, rng.uniform(4, 20), colour, cv::FILLED);
      else
        cv::rectangle(im, cv::Rect(c.x, c.y, rng.uniform(5, 30), rng.uniform(5, 30)), colour, cv::FILLED);
    }
    return im;
  }();
  return tex;
}

// Frame k: the window moved by (3, 1) pixels per frame.
cv::Mat frame(int k, int w = kW, int h = kH) { return texture()(cv::Rect(3 * k % 300, k % 200, w, h)).clone(); }

double psnr(const cv::Mat& a, const cv::Mat& b) {
  const double mse = cv::norm(a, b, cv::NORM_L2SQR) / double(a.total() * a.channels());
  return mse == 0 ? 99.0 : 10.0 * std::log10(255.0 * 255.0 / mse);
}

bool same(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

std::uint32_t le32(const Bytes& p, std::size_t at) {
  return std::uint32_t(p[at]) | std::uint32_t(p[at + 1]) << 8 | std::uint32_t(p[at + 2]) << 16 |
         std::uint32_t(p[at + 3]) << 24;
}
void set_le32(Bytes& p, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[at + std::size_t(i)] = std::uint8_t(v >> (8 * i));
}
// Recomputes the header CRC (as a hostile peer would after changing the packet).
void reseal(Bytes& p) {
  uLong crc = crc32(0L, p.data(), 12);
  crc = crc32(crc, p.data() + kH264HeaderBytes, uInt(p.size() - kH264HeaderBytes));
  set_le32(p, 12, std::uint32_t(crc));
}

// NAL unit types of an annex-B bitstream.
std::set<int> nal_types(const Bytes& packet) {
  std::set<int> types;
  for (std::size_t i = kH264HeaderBytes; i + 3 < packet.size(); ++i)
    if (packet[i] == 0 && packet[i + 1] == 0 && packet[i + 2] == 1) types.insert(packet[i + 3] & 0x1f);
  return types;
}

// Stream used by the loss/corruption tests: kStream frames, key frames at 0, 10 and 20.
constexpr int kStream = 30;
bool forced_key(int k) { return k == 10 || k == 20; }
struct Stream {
  std::vector<Bytes> packets;
  std::vector<cv::Mat> decoded;  // by an uninterrupted decoder
};
const Stream& stream() {
  static const Stream s = [] {
    Stream out;
    H264Encoder enc(kW, kH);
    H264Decoder dec(kW, kH);
    for (int k = 0; k < kStream; ++k) {
      out.packets.push_back(enc.encode(frame(k), forced_key(k)));
      out.decoded.push_back(dec.decode(out.packets.back().data(), out.packets.back().size(), "reference"));
    }
    return out;
  }();
  return s;
}
int next_key_after(int k) {
  for (int i = k + 1; i < kStream; ++i)
    if (is_h264_key_packet(stream().packets[std::size_t(i)].data(), kH264HeaderBytes)) return i;
  return kStream;
}

// Feeds packets[from..to) expecting each to decode exactly as the reference.
void expect_decodes(H264Decoder& dec, int from, int to) {
  for (int k = from; k < to; ++k) {
    const Bytes& p = stream().packets[std::size_t(k)];
    cv::Mat out;
    ASSERT_NO_THROW(out = dec.decode(p.data(), p.size(), "test")) << "frame " << k;
    EXPECT_TRUE(same(out, stream().decoded[std::size_t(k)])) << "frame " << k;
    EXPECT_FALSE(dec.waiting_for_key());
  }
}
// Feeds packets[from..next key) expecting each to be refused while waiting; returns the key's index.
int expect_refused_until_key(H264Decoder& dec, int from) {
  int k = from;
  for (; k < kStream && !is_h264_key_packet(stream().packets[std::size_t(k)].data(), kH264HeaderBytes); ++k) {
    const Bytes& p = stream().packets[std::size_t(k)];
    EXPECT_THROW(dec.decode(p.data(), p.size(), "test"), InputError) << "frame " << k;
    EXPECT_TRUE(dec.waiting_for_key());
  }
  return k;
}

TEST(H264, RoundTrip60FramesKeepsQuality) {
  H264Encoder enc(kW, kH);
  H264Decoder dec(kW, kH);
  EXPECT_TRUE(dec.waiting_for_key());
  double worst = 99, worst_jpeg = 99;
  std::size_t bytes = 0, jpeg_bytes = 0;
  for (int k = 0; k < 60; ++k) {
    const cv::Mat in = frame(k);
    const Bytes jpeg = encode_rgb(in, CodecOptions{});  // q75, the default colour codec
    jpeg_bytes += jpeg.size();
    worst_jpeg = std::min(worst_jpeg, psnr(in, decode_rgb(RgbCodec::kJpeg, jpeg.data(), jpeg.size(), kW, kH, "jpeg")));
    const Bytes p = enc.encode(in);
    bytes += p.size();
    EXPECT_EQ(le32(p, 4), std::uint32_t(k));
    EXPECT_EQ(is_h264_key_packet(p.data(), p.size()), k == 0) << "frame " << k;  // key interval 300
    const cv::Mat out = dec.decode(p.data(), p.size(), "test");
    ASSERT_EQ(out.type(), CV_8UC3);
    ASSERT_EQ(out.size(), in.size());
    worst = std::min(worst, psnr(in, out));
  }
  // Measured at the defaults (deterministic, threads 1): worst frame 30.4 dB in 75 KB for the 60
  // frames; JPEG q75 31.6 dB in 227 KB. The texture's fine noise is harder than a camera image.
  EXPECT_GT(worst, 29.0);
  EXPECT_GT(worst_jpeg, 29.0);
  EXPECT_LT(bytes * 2, jpeg_bytes);
  EXPECT_EQ(dec.stats().decoded, 60u);
  EXPECT_FALSE(dec.waiting_for_key());
  EXPECT_EQ(enc.next_index(), 60u);
}

TEST(H264, KeyPacketsCarrySpsAndPpsInBand) {
  for (int k = 0; k < kStream; ++k) {
    const Bytes& p = stream().packets[std::size_t(k)];
    const std::set<int> types = nal_types(p);
    if (k == 0 || forced_key(k)) {
      EXPECT_TRUE(is_h264_key_packet(p.data(), p.size())) << "frame " << k;
      EXPECT_TRUE(types.count(7) && types.count(8) && types.count(5)) << "frame " << k;  // SPS, PPS, IDR slice
    } else {
      EXPECT_FALSE(is_h264_key_packet(p.data(), p.size())) << "frame " << k;
      EXPECT_TRUE(types.count(1) && !types.count(5) && !types.count(7)) << "frame " << k;
    }
  }
}

TEST(H264, ForcedAndPeriodicKeyFramesContinueTheCount) {
  H264Options o;
  o.key_interval = 8;
  H264Encoder enc(kW, kH, o);
  for (int k = 0; k < 20; ++k) {
    const Bytes p = enc.encode(frame(k), k == 5);
    EXPECT_EQ(le32(p, 4), std::uint32_t(k));
    // x264 counts the interval from the last IDR, forced ones included.
    EXPECT_EQ(is_h264_key_packet(p.data(), p.size()), k == 0 || k == 5 || k == 13) << "frame " << k;
  }
}

TEST(H264, TwoEncodersGiveIdenticalBytes) {
  H264Encoder a(kW, kH), b(kW, kH);
  for (int k = 0; k < 25; ++k) {
    const cv::Mat in = frame(k);
    EXPECT_EQ(a.encode(in, k == 12), b.encode(in, k == 12)) << "frame " << k;
  }
  H264Encoder again(kW, kH);  // and the same as the shared stream, encoded earlier in this process
  for (int k = 0; k < kStream; ++k) EXPECT_EQ(again.encode(frame(k), forced_key(k)), stream().packets[std::size_t(k)]);
}

class H264LossOfOnePacket : public ::testing::TestWithParam<int> {};

TEST_P(H264LossOfOnePacket, GapThenRefusedThenExactResyncAtKey) {
  const int lost = GetParam();
  H264Decoder dec(kW, kH);
  expect_decodes(dec, 0, lost);
  int k = lost + 1;
  if (k < kStream && !is_h264_key_packet(stream().packets[std::size_t(k)].data(), kH264HeaderBytes)) {
    const Bytes& p = stream().packets[std::size_t(k)];
    EXPECT_THROW(dec.decode(p.data(), p.size(), "test"), InputError);
    EXPECT_TRUE(dec.waiting_for_key());
    // Losing the first key frame leaves a new decoder waiting: no gap to see.
    EXPECT_EQ(dec.stats().gaps, lost == 0 ? 0u : 1u);
    k = expect_refused_until_key(dec, k + 1);
  }
  EXPECT_EQ(k, std::min(kStream, next_key_after(lost)));
  expect_decodes(dec, k, kStream);
  EXPECT_EQ(dec.stats().corrupt, 0u);
  EXPECT_EQ(dec.stats().stale, 0u);
  EXPECT_EQ(dec.stats().decoded, std::uint64_t(lost + (kStream - k)));
}

INSTANTIATE_TEST_SUITE_P(EveryIndex, H264LossOfOnePacket, ::testing::Range(0, kStream));

TEST(H264, SwappedNonKeyPacketsBreakTheChainUntilTheKey) {
  const auto& p = stream().packets;
  H264Decoder dec(kW, kH);
  expect_decodes(dec, 0, 4);
  EXPECT_THROW(dec.decode(p[5].data(), p[5].size(), "test"), InputError);  // gap: 4 missing
  EXPECT_EQ(dec.stats().gaps, 1u);
  EXPECT_THROW(dec.decode(p[4].data(), p[4].size(), "test"), InputError);  // late, but waiting
  EXPECT_EQ(dec.stats().refused_waiting, 1u);
  EXPECT_EQ(expect_refused_until_key(dec, 6), 10);
  expect_decodes(dec, 10, kStream);
}

TEST(H264, PacketLateBehindAKeyIsStaleAndKeepsTheChain) {
  const auto& p = stream().packets;
  H264Decoder dec(kW, kH);
  expect_decodes(dec, 0, 9);
  expect_decodes(dec, 10, 11);                                             // key 10 before 9
  EXPECT_THROW(dec.decode(p[9].data(), p[9].size(), "test"), InputError);  // stale
  EXPECT_FALSE(dec.waiting_for_key());
  EXPECT_EQ(dec.stats().stale, 1u);
  expect_decodes(dec, 11, kStream);
}

TEST(H264, DuplicatePacketIsStaleAndKeepsTheChain) {
  const auto& p = stream().packets;
  H264Decoder dec(kW, kH);
  expect_decodes(dec, 0, 6);
  EXPECT_THROW(dec.decode(p[5].data(), p[5].size(), "test"), InputError);
  EXPECT_THROW(dec.decode(p[2].data(), p[2].size(), "test"), InputError);
  EXPECT_EQ(dec.stats().stale, 2u);
  expect_decodes(dec, 6, kStream);
}

TEST(H264, RestartedEncoderIsAcceptedAtItsFirstKey) {
  H264Decoder dec(kW, kH);
  expect_decodes(dec, 0, 15);
  expect_decodes(dec, 0, 5);  // index 0 again, but a key frame: a new stream
}

struct Corruption {
  std::string name;
  void (*apply)(Bytes&);
};
void PrintTo(const Corruption& c, std::ostream* os) { *os << c.name; }

class H264CorruptPacket : public ::testing::TestWithParam<Corruption> {};

TEST_P(H264CorruptPacket, InputErrorThenResyncAtTheNextKey) {
  for (int bad : {0, 3, 10}) {  // a key frame, a P frame, a forced key frame
    H264Decoder dec(kW, kH);
    expect_decodes(dec, 0, bad);
    Bytes p = stream().packets[std::size_t(bad)];
    GetParam().apply(p);
    EXPECT_THROW(dec.decode(p.data(), p.size(), "robot 1 rgb"), InputError) << "frame " << bad;
    EXPECT_TRUE(dec.waiting_for_key());
    EXPECT_EQ(dec.stats().corrupt, 1u);
    const int key = expect_refused_until_key(dec, bad + 1);
    EXPECT_EQ(key, next_key_after(bad));
    expect_decodes(dec, key, kStream);
  }
}

INSTANTIATE_TEST_SUITE_P(Kinds, H264CorruptPacket,
                         ::testing::Values(Corruption{"FlippedBitstreamByte",
                                                      [](Bytes& p) { p[p.size() / 2] ^= 0x10; }},
                                           Corruption{"FlippedIndexByte", [](Bytes& p) { p[4] ^= 0x01; }},
                                           Corruption{"FlippedKeyFlag", [](Bytes& p) { p[3] ^= 0x01; }},
                                           Corruption{"TruncatedHeader", [](Bytes& p) { p.resize(10); }},
                                           Corruption{"TruncatedBitstream", [](Bytes& p) { p.resize(p.size() - 7); }},
                                           Corruption{"Empty", [](Bytes& p) { p.clear(); }},
                                           Corruption{"BadMagic", [](Bytes& p) { p[0] = 'J'; }},
                                           Corruption{"BadVersion",
                                                      [](Bytes& p) {
                                                        p[2] = 2;
                                                        reseal(p);
                                                      }},
                                           Corruption{"UnknownFlag",
                                                      [](Bytes& p) {
                                                        p[3] |= 0x80;
                                                        reseal(p);
                                                      }},
                                           Corruption{"LengthMismatch",
                                                      [](Bytes& p) {
                                                        set_le32(p, 8, le32(p, 8) + 1);
                                                        reseal(p);
                                                      }},
                                           Corruption{"AbsurdLength",
                                                      [](Bytes& p) {
                                                        set_le32(p, 8, 0xfffffff0u);
                                                        reseal(p);
                                                      }},
                                           Corruption{"NoBitstream",
                                                      [](Bytes& p) {
                                                        p.resize(kH264HeaderBytes);
                                                        set_le32(p, 8, 0);
                                                        reseal(p);
                                                      }},
                                           Corruption{"GarbageWithValidCrc",
                                                      [](Bytes& p) {
                                                        for (std::size_t i = kH264HeaderBytes; i < p.size(); ++i)
                                                          p[i] = std::uint8_t(i * 37);
                                                        reseal(p);
                                                      }}),
                         [](const auto& info) { return info.param.name; });

// A hostile peer seals damaged bitstreams with a valid CRC: libavcodec sees them. Whatever comes
// out is an InputError or a picture of exactly the expected size, and the next key resyncs.
TEST(H264, DamagedBitstreamsWithValidCrcNeverEscapeTheSize) {
  std::mt19937 rng(3);
  int refused = 0;
  for (int trial = 0; trial < 60; ++trial) {
    H264Decoder dec(kW, kH);
    const int bad = trial % 2 ? 0 : 1 + trial % 9;
    expect_decodes(dec, 0, bad);
    Bytes p = stream().packets[std::size_t(bad)];
    for (int n = 0; n < 1 + trial % 5; ++n) {
      const std::size_t at = kH264HeaderBytes + rng() % (p.size() - kH264HeaderBytes);
      p[at] = std::uint8_t(rng());
    }
    reseal(p);
    try {
      const cv::Mat out = dec.decode(p.data(), p.size(), "test");
      EXPECT_EQ(out.size(), cv::Size(kW, kH));
      EXPECT_EQ(out.type(), CV_8UC3);
    } catch (const InputError&) {
      ++refused;
      EXPECT_TRUE(dec.waiting_for_key());
    }
    if (dec.waiting_for_key()) {
      expect_decodes(dec, 10, kStream);
    }
  }
  EXPECT_GT(refused, 0);
}

TEST(H264, StreamOfAnotherSizeIsRefused) {
  H264Encoder big(64, 48);
  H264Decoder small(32, 32);
  const Bytes p = big.encode(frame(0, 64, 48));
  EXPECT_THROW(small.decode(p.data(), p.size(), "test"), InputError);
  EXPECT_TRUE(small.waiting_for_key());

  H264Encoder tiny(32, 32);
  H264Decoder larger(64, 48);
  const Bytes q = tiny.encode(frame(0, 32, 32));
  EXPECT_THROW(larger.decode(q.data(), q.size(), "test"), InputError);
  EXPECT_EQ(larger.stats().corrupt, 1u);
}

TEST(H264, BadConfigurationAndInputAreRefused) {
  EXPECT_THROW(H264Encoder(161, 120), ConfigError);
  EXPECT_THROW(H264Encoder(160, 121), ConfigError);
  EXPECT_THROW(H264Decoder(33, 32), ConfigError);
  EXPECT_THROW(H264Decoder(0, 32), ConfigError);
  EXPECT_THROW(H264Decoder(kMaxImageSide + 2, 32), ConfigError);
  H264Options o;
  o.crf = 52;
  EXPECT_THROW(o.validate(), ConfigError);
  o = H264Options{};
  o.preset = "quick";
  EXPECT_THROW(H264Encoder(kW, kH, o), ConfigError);
  o = H264Options{};
  o.tune = "psnr";  // without zerolatency x264 would delay packets
  EXPECT_THROW(o.validate(), ConfigError);
  o.tune = "zerolatency,fast";
  EXPECT_THROW(o.validate(), ConfigError);
  o.tune = "zerolatency";
  EXPECT_NO_THROW(o.validate());
  o = H264Options{};
  o.key_interval = 0;
  EXPECT_THROW(o.validate(), ConfigError);
  o = H264Options{};
  o.frame_rate = 0;
  EXPECT_THROW(o.validate(), ConfigError);
  EXPECT_NO_THROW(H264Options{}.validate());

  H264Encoder enc(kW, kH);
  EXPECT_THROW(enc.encode(frame(0, kW + 2, kH)), std::invalid_argument);
  cv::Mat grey;
  cv::cvtColor(frame(0), grey, cv::COLOR_BGR2GRAY);
  EXPECT_THROW(enc.encode(grey), std::invalid_argument);
  EXPECT_EQ(enc.next_index(), 0u);
}

TEST(H264, KeyPacketHelperReadsOnlyTheHeader) {
  const Bytes& key = stream().packets[0];
  const Bytes& p = stream().packets[1];
  EXPECT_TRUE(is_h264_key_packet(key.data(), kH264HeaderBytes));
  EXPECT_FALSE(is_h264_key_packet(key.data(), kH264HeaderBytes - 1));
  EXPECT_FALSE(is_h264_key_packet(p.data(), p.size()));
  Bytes bad = key;
  bad[1] = 'X';
  EXPECT_FALSE(is_h264_key_packet(bad.data(), bad.size()));
}

}  // namespace
}  // namespace cslam::video
