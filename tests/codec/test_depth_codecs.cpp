// The zstd depth codec's decoder against its encoder on every kind of hole pattern, and damaged
// ranks. The decoder runs two rows' prediction chains side by side, except where a row's first
// valid pixel has no valid pixel above it (its prediction is the last rank of the row before):
// these cases exercise both paths and every row-pair boundary.
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <zstd.h>

#include "codec/depth_codecs.h"
#include "core/error.h"

namespace cslam {
namespace {

using Pixels = std::vector<std::uint16_t>;

// A smooth ramp with noise and a few far values, holes where `hole(x, y)` says.
template <typename HoleFn>
Pixels make_depth(int w, int h, unsigned seed, HoleFn hole) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> noise(-4, 4), far(0, 199);
  Pixels d(std::size_t(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      int v = 3000 + 11 * x + 5 * y + noise(rng);
      if (far(rng) == 0) v = 60000 + noise(rng);
      d[std::size_t(y) * w + x] = hole(x, y) ? 0 : std::uint16_t(v);
    }
  return d;
}

Pixels round_trip(const Pixels& d, int w, int h) {
  const std::vector<std::uint8_t> bytes = depth_codec::zstd_delta_encode(d.data(), w, h, 1);
  Pixels back(d.size(), 0xBEEF);
  depth_codec::zstd_delta_decode(bytes.data(), bytes.size(), back.data(), w, h, "test");
  return back;
}

TEST(ZstdDelta, RoundTripsRandomHolesAtEveryDensityAndSize) {
  const std::vector<std::pair<int, int>> sizes = {{1, 1}, {1, 6}, {7, 1}, {5, 2}, {9, 3}, {16, 7}, {33, 10}, {64, 48}};
  for (const auto& [w, h] : sizes)
    for (double density : {0.0, 0.02, 0.3, 0.7, 0.98, 1.0})
      for (unsigned seed : {1u, 2u, 3u}) {
        std::mt19937 rng(seed * 7919u + unsigned(w * 131 + h));
        std::bernoulli_distribution is_hole(density);
        std::vector<char> holes(std::size_t(w) * h);
        for (auto& c : holes) c = is_hole(rng);
        const Pixels d = make_depth(w, h, seed, [&](int x, int y) { return holes[std::size_t(y) * w + x] != 0; });
        EXPECT_EQ(round_trip(d, w, h), d) << w << "x" << h << " holes " << density << " seed " << seed;
      }
}

TEST(ZstdDelta, RoundTripsRowsThatStartUnderHolesAndEmptyRows) {
  const int w = 24, h = 11;
  // Row 1 starts valid under a hole (the pair falls back to one row at a time); row 3 is empty;
  // row 5 starts late under a valid pixel (paired); row 6 starts under a hole after a valid
  // stretch of row 5; rows 8-10: a left hole column under which every row starts at x = 1.
  const auto hole = [&](int x, int y) {
    switch (y) {
      case 0:
        return x < 3;
      case 1:
        return x < 1;
      case 3:
        return true;
      case 5:
        return x < 10;
      case 6:
        return x < 4 || (x > 12 && x < 15);
      default:
        return y >= 8 ? x == 0 || (x == 5 && y == 9) : false;
    }
  };
  for (unsigned seed : {4u, 5u}) {
    const Pixels d = make_depth(w, h, seed, hole);
    EXPECT_EQ(round_trip(d, w, h), d) << "seed " << seed;
    // Also with every height from 1 up: each row ends a pair or stands alone somewhere.
    for (int rows = 1; rows < h; ++rows) {
      const Pixels part(d.begin(), d.begin() + std::ptrdiff_t(w) * rows);
      EXPECT_EQ(round_trip(part, w, rows), part) << rows << " rows, seed " << seed;
    }
  }
}

// The payload (before zstd) of `d`, and the same re-compressed after `edit` changed it.
template <typename EditFn>
std::vector<std::uint8_t> edited(const Pixels& d, int w, int h, EditFn edit) {
  const std::vector<std::uint8_t> bytes = depth_codec::zstd_delta_encode(d.data(), w, h, 1);
  std::vector<std::uint8_t> payload(ZSTD_getFrameContentSize(bytes.data(), bytes.size()));
  EXPECT_EQ(ZSTD_decompress(payload.data(), payload.size(), bytes.data(), bytes.size()), payload.size());
  edit(payload);
  std::vector<std::uint8_t> out(ZSTD_compressBound(payload.size()));
  out.resize(ZSTD_compress(out.data(), out.size(), payload.data(), payload.size(), 1));
  return out;
}

TEST(ZstdDelta, ARankOutsideTheTableOrABadMaskByteIsRejectedInEitherRowOfAPair) {
  const int w = 8, h = 4;
  const Pixels d = make_depth(w, h, 6, [](int, int) { return false; });
  std::uint32_t table = 0;  // distinct values, read from the payload
  Pixels back(d.size());
  for (int pixel : {0, 5, w + 2, 2 * w + 7, 3 * w}) {  // rows 0 and 1 are a pair, 2 and 3 another
    const auto bytes = edited(d, w, h, [&](std::vector<std::uint8_t>& p) {
      table = std::uint32_t(p[0]) | (std::uint32_t(p[1]) << 8);
      const std::size_t n = std::size_t(w) * h, residuals = 4 + 2 * std::size_t(table) + n;
      p[residuals + n + std::size_t(pixel)] ^= 0x40;  // the high byte: a residual of +-8192 ranks
    });
    ASSERT_GT(table, 0u);
    EXPECT_THROW(depth_codec::zstd_delta_decode(bytes.data(), bytes.size(), back.data(), w, h, "test"), InputError)
        << "pixel " << pixel;
  }
  const auto bad_mask = edited(d, w, h, [&](std::vector<std::uint8_t>& p) {
    const std::uint32_t t = std::uint32_t(p[0]) | (std::uint32_t(p[1]) << 8);
    p[4 + 2 * std::size_t(t) + std::size_t(w) + 3] = 2;
  });
  EXPECT_THROW(depth_codec::zstd_delta_decode(bad_mask.data(), bad_mask.size(), back.data(), w, h, "test"), InputError);
}

}  // namespace
}  // namespace cslam
