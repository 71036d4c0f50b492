// The byte budget (codec/byte_budget.h) and the full frames' colour it chooses
// (ImageEncoder::rgb_within).
#include <cmath>
#include <numeric>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "codec/byte_budget.h"
#include "codec/image_encoder.h"
#include "common/test_images.h"
#include "core/error.h"

namespace cslam {
namespace {

cv::Mat textured_bgr(int w, int h, unsigned seed) { return test::blurred_noise_bgr(w, h, seed, 1.2); }

ByteBudgetConfig budget_of(double bytes_per_s, double frame_rate = 10, double burst_s = 1) {
  ByteBudgetConfig c;
  c.bytes_per_s = bytes_per_s;
  c.frame_rate = frame_rate;
  c.burst_s = burst_s;
  return c;
}

TEST(ByteBudget, StartsEmptySavesUpBySendingLessAndPaysBackWhatItOwes) {
  ByteBudget b(budget_of(10000));  // 1000 B a frame, at most 10000 B saved
  EXPECT_TRUE(b.enabled());
  EXPECT_EQ(b.allowance(), 1000u);  // its own share: no start-up burst
  for (int i = 0; i < 4; ++i) b.add(100);
  EXPECT_EQ(b.allowance(), 4u * 900u + 1000u);
  for (int i = 0; i < 20; ++i) b.add(0);
  EXPECT_EQ(b.allowance(), 10000u);  // at most burst_s of budget
  b.add(10000);                      // a frame spends it all
  EXPECT_EQ(b.allowance(), 1000u);
  b.add(3000);  // frames never wait: it owes 2000
  EXPECT_EQ(b.allowance(), 0u);
  b.add(0);
  EXPECT_EQ(b.allowance(), 0u);  // -1000 + 1000
  b.add(0);
  EXPECT_EQ(b.allowance(), 1000u);
  EXPECT_EQ(b.image_allowance(200), 1000u - 200u - ByteBudget::kHeaderBytes);
  EXPECT_EQ(b.image_allowance(2000), 0u);
}

// Whatever the frames want: over any run of frames, those that kept to their allowance send at
// most the run's budget plus the bucket's capacity, and a whole run from the start at most its
// budget.
TEST(ByteBudget, FramesWithinTheirAllowanceStayWithinTheBudget) {
  ByteBudget b(budget_of(30000, 30, 2));  // 1000 B a frame, 60000 B at most saved
  std::vector<double> sent;
  cv::RNG rng(7);
  for (int i = 0; i < 2000; ++i) {
    const std::size_t want = std::size_t(rng.uniform(0, 4000));
    const std::size_t bytes = std::min(want, b.allowance());
    b.add(bytes);
    sent.push_back(double(bytes));
  }
  EXPECT_LE(std::accumulate(sent.begin(), sent.end(), 0.0), 1000.0 * 2000);
  EXPECT_GT(std::accumulate(sent.begin(), sent.end(), 0.0), 0.9 * 1000.0 * 2000);  // and spends it
  for (std::size_t len : {10, 60, 300})
    for (std::size_t i = 0; i + len <= sent.size(); ++i)
      EXPECT_LE(std::accumulate(sent.begin() + long(i), sent.begin() + long(i + len), 0.0), 1000.0 * len + 60000)
          << i << " + " << len;
}

TEST(ByteBudget, ConfigIsChecked) {
  EXPECT_NO_THROW(ByteBudgetConfig().validate());
  EXPECT_FALSE(ByteBudget(ByteBudgetConfig()).enabled());
  EXPECT_THROW(ByteBudget(budget_of(-1)), ConfigError);
  EXPECT_THROW(ByteBudget(budget_of(std::nan(""))), ConfigError);
  EXPECT_THROW(ByteBudget(budget_of(1e6, 0)), ConfigError);
  EXPECT_THROW(ByteBudget(budget_of(1e6, 30, 0)), ConfigError);
  ByteBudgetConfig c = budget_of(1e6);
  c.jpeg_qualities = {90, 95};
  EXPECT_THROW(c.validate(), ConfigError);
  c.jpeg_qualities = {101};
  EXPECT_THROW(c.validate(), ConfigError);
  c.jpeg_qualities = {};
  EXPECT_NO_THROW(c.validate());
}

TEST(RgbWithin, TakesTheFinestJpegThatFitsElseTheStreamsOwnCodec) {
  const cv::Mat bgr = textured_bgr(160, 120, 3);
  CodecOptions jpeg95;
  jpeg95.jpeg_quality = 95;
  CodecOptions jpeg85 = jpeg95;
  jpeg85.jpeg_quality = 85;
  const std::size_t q95 = encode_rgb(bgr, jpeg95).size(), q85 = encode_rgb(bgr, jpeg85).size();
  ASSERT_GT(q95, q85);

  CodecOptions intra;
  intra.rgb = RgbCodec::kH264Intra;
  const std::vector<int> ladder = {95, 90, 85};
  ImageEncoder images(intra, bgr.size());
  EncodedRgb r = images.rgb_within(bgr, q95, ladder);
  EXPECT_EQ(r.codec, RgbCodec::kJpeg);
  EXPECT_EQ(r.jpeg_quality, 95);
  EXPECT_TRUE(r.finer);
  EXPECT_EQ(r.bytes, encode_rgb(bgr, jpeg95));
  r = images.rgb_within(bgr, q85, ladder);
  EXPECT_EQ(r.jpeg_quality, 85);
  EXPECT_EQ(r.bytes.size(), q85);
  r = images.rgb_within(bgr, q85 - 1, ladder);
  EXPECT_EQ(r.codec, RgbCodec::kH264Intra);
  EXPECT_EQ(r.jpeg_quality, 0);
  EXPECT_FALSE(r.finer);
  EXPECT_FALSE(r.bytes.empty());
  const cv::Mat back = decode_rgb(r.codec, r.bytes.data(), r.bytes.size(), bgr.cols, bgr.rows, "test");
  EXPECT_EQ(back.size(), bgr.size());

  // A JPEG stream is only ever made finer; lossless ones are never replaced.
  CodecOptions jpeg90 = jpeg95;
  jpeg90.jpeg_quality = 90;
  ImageEncoder jpeg_images(jpeg90);
  r = jpeg_images.rgb_within(bgr, q85, ladder);
  EXPECT_EQ(r.jpeg_quality, 90);
  EXPECT_FALSE(r.finer);  // the stream's own
  EXPECT_EQ(r.bytes, encode_rgb(bgr, jpeg90));
  CodecOptions png;
  png.rgb = RgbCodec::kPng;
  ImageEncoder png_images(png);
  r = png_images.rgb_within(bgr, 1u << 30, ladder);
  EXPECT_EQ(r.codec, RgbCodec::kPng);
  EXPECT_FALSE(r.finer);
  EXPECT_THROW(images.rgb_within(cv::Mat(120, 160, CV_8UC1), 1u << 30, ladder), std::invalid_argument);
}

// A quality whose last picture was far over its allowance is not tried again on the next frame
// (pictures change little between a robot's full frames; each trial is a JPEG encoding).
TEST(RgbWithin, SkipsAQualityThatWasFarOverTheLastTime) {
  CodecOptions q95, q90;
  q95.jpeg_quality = 95;
  q90.jpeg_quality = 90;
  cv::Mat calm;
  cv::GaussianBlur(textured_bgr(160, 120, 5), calm, cv::Size(9, 9), 4);
  const std::size_t calm95 = encode_rgb(calm, q95).size(), calm90 = encode_rgb(calm, q90).size();
  // A busier picture whose q95 is far over what fits the calm one's q95, and its q90 is not.
  cv::Mat busy;
  bool found = false;
  for (int noise = 1; noise <= 40 && !found; ++noise) {
    cv::Mat grain(calm.size(), CV_16SC3);
    cv::RNG(11).fill(grain, cv::RNG::NORMAL, 0, noise);
    calm.convertTo(busy, CV_16SC3);
    busy += grain;
    busy.convertTo(busy, CV_8UC3);
    const double b95 = double(encode_rgb(busy, q95).size()), b90 = double(encode_rgb(busy, q90).size());
    found = b95 > 1.25 * double(calm95) && b90 <= 1.25 * double(calm95);
  }
  ASSERT_TRUE(found);

  CodecOptions intra;
  intra.rgb = RgbCodec::kH264Intra;
  const std::vector<int> ladder = {95, 90};
  ImageEncoder fresh(intra, calm.size());
  EXPECT_EQ(fresh.rgb_within(calm, calm95, ladder).jpeg_quality, 95);  // nothing known: tried
  ImageEncoder seen(intra, calm.size());
  EXPECT_EQ(seen.rgb_within(busy, 1, ladder).codec, RgbCodec::kH264Intra);  // both tried, both over
  const EncodedRgb r = seen.rgb_within(calm, calm95, ladder);               // q95 skipped
  EXPECT_EQ(r.jpeg_quality, 90);
  EXPECT_EQ(r.bytes.size(), calm90);
  EXPECT_EQ(seen.rgb_within(calm, calm95, ladder).jpeg_quality, 90);  // still known as far over
  // With room near the last size it is tried again, and then known as it is now.
  EXPECT_EQ(seen.rgb_within(calm, 10 * calm95, ladder).jpeg_quality, 95);
  EXPECT_EQ(seen.rgb_within(calm, calm95, ladder).jpeg_quality, 95);
}

}  // namespace
}  // namespace cslam
