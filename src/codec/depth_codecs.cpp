#include "codec/depth_codecs.h"

#include <algorithm>
#include <cstring>
#include <memory>

#include <zstd.h>

#include "core/error.h"

namespace cslam::depth_codec {

namespace {

// Nibble writer/reader: two 4-bit nibbles per byte, low nibble first.
class NibbleWriter {
 public:
  explicit NibbleWriter(std::vector<std::uint8_t>& out) : out_(out) {}
  void put(std::uint8_t nibble) {
    if (half_) {
      out_.back() |= std::uint8_t(nibble << 4);
    } else {
      out_.push_back(nibble);
    }
    half_ = !half_;
  }
  // Variable length: 3 data bits per nibble, bit 3 set when more nibbles follow.
  void put_varint(std::uint32_t value) {
    do {
      std::uint8_t nibble = value & 7u;
      value >>= 3;
      if (value) nibble |= 8u;
      put(nibble);
    } while (value);
  }

 private:
  std::vector<std::uint8_t>& out_;
  bool half_ = false;
};

class NibbleReader {
 public:
  NibbleReader(const std::uint8_t* data, std::size_t size, const std::string& source)
      : data_(data), size_(size), source_(source) {}
  std::uint32_t get_varint() {
    std::uint32_t value = 0;
    for (int shift = 0; shift < 33; shift += 3) {
      const std::uint8_t nibble = get();
      value |= std::uint32_t(nibble & 7u) << shift;
      if (!(nibble & 8u)) return value;
    }
    throw InputError(source_, "RVL depth: variable-length number too long");
  }

 private:
  std::uint8_t get() {
    const std::size_t byte = pos_ >> 1;
    if (byte >= size_) throw InputError(source_, "RVL depth: data truncated");
    const std::uint8_t nibble = (pos_ & 1) ? (data_[byte] >> 4) : (data_[byte] & 0x0f);
    ++pos_;
    return nibble;
  }
  const std::uint8_t* data_;
  std::size_t size_, pos_ = 0;
  const std::string& source_;
};

inline std::uint32_t zigzag32(std::int32_t v) { return (std::uint32_t(v) << 1) ^ std::uint32_t(v >> 31); }
inline std::int32_t unzigzag32(std::uint32_t z) { return std::int32_t(z >> 1) ^ -std::int32_t(z & 1); }

}  // namespace

std::vector<std::uint8_t> rvl_encode(const std::uint16_t* pixels, std::size_t count) {
  std::vector<std::uint8_t> out;
  out.reserve(count / 2);
  NibbleWriter writer(out);
  std::size_t i = 0;
  std::int32_t previous = 0;
  while (i < count) {
    std::size_t zeros = 0;
    while (i + zeros < count && pixels[i + zeros] == 0) ++zeros;
    i += zeros;
    std::size_t nonzeros = 0;
    while (i + nonzeros < count && pixels[i + nonzeros] != 0) ++nonzeros;
    writer.put_varint(std::uint32_t(zeros));
    writer.put_varint(std::uint32_t(nonzeros));
    for (std::size_t k = 0; k < nonzeros; ++k, ++i) {
      const std::int32_t value = pixels[i];
      writer.put_varint(zigzag32(value - previous));
      previous = value;
    }
  }
  return out;
}

void rvl_decode(const std::uint8_t* data, std::size_t size, std::uint16_t* pixels, std::size_t count,
                const std::string& source) {
  NibbleReader reader(data, size, source);
  std::size_t i = 0;
  std::int32_t previous = 0;
  while (i < count) {
    const std::uint32_t zeros = reader.get_varint();
    if (zeros > count - i) throw InputError(source, "RVL depth: zero run past the end of the image");
    for (std::uint32_t k = 0; k < zeros; ++k) pixels[i++] = 0;
    const std::uint32_t nonzeros = reader.get_varint();
    if (nonzeros > count - i) throw InputError(source, "RVL depth: value run past the end of the image");
    for (std::uint32_t k = 0; k < nonzeros; ++k) {
      const std::int64_t value = std::int64_t(previous) + unzigzag32(reader.get_varint());
      if (value <= 0 || value > 65535) throw InputError(source, "RVL depth: decoded value out of range");
      pixels[i++] = std::uint16_t(value);
      previous = std::int32_t(value);
    }
  }
}

namespace {

// Predicts a valid pixel's value rank from its causal neighbours that are valid (not holes):
// the LOCO-I / JPEG-LS median edge detector when left (a), upper (b) and upper-left (c) are all
// valid, else the one valid of a/b (or their mean), else the last valid rank seen (`last`).
// The left neighbour comes as its validity and rank: the decoder keeps both in registers (the
// rank just decoded starts the next pixel's prediction: a chain it need not pass through memory).
inline std::int32_t predict_from(bool va, std::int32_t a, const std::uint16_t* above, const std::uint8_t* above_valid,
                                 int x, std::int32_t last) {
  const bool vb = above && above_valid[x];
  const bool vc = above && x > 0 && above_valid[x - 1];
  if (va && vb) {
    const std::int32_t b = above[x];
    if (!vc) return (a + b) / 2;
    const std::int32_t c = above[x - 1];
    // Branch-free form (selects compile to conditional moves; depth noise defeats prediction).
    const std::int32_t hi = std::max(a, b), lo = std::min(a, b);
    const std::int32_t p = c >= hi ? lo : a + b - c;
    return c <= lo ? hi : p;
  }
  if (va) return a;
  if (vb) return above[x];
  return last;
}

// The encoder's form: the left neighbour read from the row.
inline std::int32_t predict(const std::uint16_t* row, const std::uint8_t* row_valid, const std::uint16_t* above,
                            const std::uint8_t* above_valid, int x, std::int32_t last) {
  return predict_from(x > 0 && row_valid[x - 1], x > 0 ? row[x - 1] : 0, above, above_valid, x, last);
}

// The decoder's view of one row: its ranks, hole mask and output, the row above (null for the
// first), its residuals from its first valid pixel on, and the last valid rank decoded before.
struct RankRow {
  std::uint16_t* ranks;
  const std::uint8_t* valid;
  const std::uint16_t* above;
  const std::uint8_t* above_valid;
  std::uint16_t* pixels;
  const std::uint8_t* low;
  const std::uint8_t* high;
  std::int32_t last;        // the last valid rank decoded (this row's or, before its first, the rows' above)
  bool left_valid = false;  // the pixel just decoded in this row is valid (its rank: last)
};

struct RankTable {
  const std::uint16_t* values;
  std::uint32_t size;
};

void put_u32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(std::uint8_t(v >> (8 * i)));
}

inline std::uint16_t zigzag16(std::int32_t residual) {
  const auto r = std::int16_t(std::uint16_t(residual));
  return std::uint16_t((std::uint16_t(r) << 1) ^ std::uint16_t(r >> 15));
}
inline std::uint16_t unzigzag16(std::uint16_t z) { return std::uint16_t((z >> 1) ^ std::uint16_t(-(z & 1))); }

// Decodes pixel x of a row (a hole is 0); false if the residual gives a rank outside the table.
// Each valid pixel's prediction needs the one decoded just before it in its row: a serial chain
// per row. The caller runs two rows' chains side by side so that the CPU overlaps them.
inline bool decode_rank(RankRow& row, int x, const RankTable& table) {
  if (!row.valid[x]) {
    row.pixels[x] = 0;
    row.left_valid = false;
    return true;
  }
  const std::uint16_t z = std::uint16_t(*row.low++ | (*row.high++ << 8));
  const std::uint16_t r =
      std::uint16_t(predict_from(row.left_valid, row.last, row.above, row.above_valid, x, row.last) + unzigzag16(z));
  if (r >= table.size) return false;
  row.ranks[x] = r;
  row.last = r;
  row.left_valid = true;
  row.pixels[x] = table.values[r];
  return true;
}

}  // namespace

// Layout before zstd:
//   u32 T; T sorted distinct non-zero depth values (u16 LE, delta-coded);
//   n bytes hole mask (1 = valid, 0 = no measurement);
//   m low bytes then m high bytes of the zig-zag prediction residuals of the valid pixels' value
//   ranks (m = number of valid pixels, raster order).
// Kinect-style depth has few distinct values (quantised disparity), so ranks are much smoother
// than raw depth units; holes are coded apart so their edges do not produce large residuals.
std::vector<std::uint8_t> zstd_delta_encode(const std::uint16_t* pixels, int width, int height, int level) {
  const std::size_t n = std::size_t(width) * std::size_t(height);
  std::vector<std::uint8_t> used(65536, 0);
  for (std::size_t i = 0; i < n; ++i) used[pixels[i]] = 1;
  std::vector<std::uint16_t> rank(65536, 0), table;
  for (std::uint32_t v = 1; v < 65536; ++v)
    if (used[v]) {
      rank[v] = std::uint16_t(table.size());
      table.push_back(std::uint16_t(v));
    }
  std::vector<std::uint8_t> payload;
  payload.reserve(4 + 2 * table.size() + 3 * n);
  put_u32(payload, std::uint32_t(table.size()));
  std::uint16_t previous = 0;
  for (std::uint16_t v : table) {
    const std::uint16_t d = std::uint16_t(v - previous);
    payload.push_back(std::uint8_t(d & 0xff));
    payload.push_back(std::uint8_t(d >> 8));
    previous = v;
  }
  std::vector<std::uint16_t> ranks(n);
  std::vector<std::uint8_t> valid(n);
  for (std::size_t i = 0; i < n; ++i) {
    valid[i] = pixels[i] != 0;
    ranks[i] = rank[pixels[i]];
  }
  payload.insert(payload.end(), valid.begin(), valid.end());
  std::vector<std::uint8_t> low(n), high(n);
  std::size_t m = 0;
  std::int32_t last = 0;
  for (int y = 0; y < height; ++y) {
    const std::size_t o = std::size_t(y) * width;
    const std::uint16_t* row = ranks.data() + o;
    const std::uint8_t* row_valid = valid.data() + o;
    const std::uint16_t* above = y > 0 ? row - width : nullptr;
    const std::uint8_t* above_valid = y > 0 ? row_valid - width : nullptr;
    for (int x = 0; x < width; ++x) {
      if (!row_valid[x]) continue;
      const std::uint16_t z = zigzag16(std::int32_t(row[x]) - predict(row, row_valid, above, above_valid, x, last));
      low[m] = std::uint8_t(z & 0xff);
      high[m++] = std::uint8_t(z >> 8);
      last = row[x];
    }
  }
  payload.insert(payload.end(), low.begin(), low.begin() + std::ptrdiff_t(m));
  payload.insert(payload.end(), high.begin(), high.begin() + std::ptrdiff_t(m));
  std::vector<std::uint8_t> out(ZSTD_compressBound(payload.size()));
  const std::size_t written = ZSTD_compress(out.data(), out.size(), payload.data(), payload.size(), level);
  if (ZSTD_isError(written))
    throw std::runtime_error(std::string("zstd compression failed: ") + ZSTD_getErrorName(written));
  out.resize(written);
  return out;
}

void zstd_delta_decode(const std::uint8_t* data, std::size_t size, std::uint16_t* pixels, int width, int height,
                       const std::string& source) {
  const std::size_t n = std::size_t(width) * std::size_t(height);
  const unsigned long long announced = ZSTD_getFrameContentSize(data, size);
  if (announced == ZSTD_CONTENTSIZE_ERROR) throw InputError(source, "zstd depth: not a zstd frame");
  const std::size_t max_payload = 4 + 2 * 65535 + 3 * n;
  if (announced == ZSTD_CONTENTSIZE_UNKNOWN || announced > max_payload || announced < 4 + n)
    throw InputError(source, "zstd depth: content size does not fit a " + std::to_string(width) + "x" +
                                 std::to_string(height) + " image");
  // Not zero-filled: zstd writes every byte it announces (checked below), and only valid pixels'
  // ranks are ever read.
  const std::unique_ptr<std::uint8_t[]> buffer(new std::uint8_t[announced]);
  const std::uint8_t* payload = buffer.get();
  const std::size_t payload_size = std::size_t(announced);
  const std::size_t got = ZSTD_decompress(buffer.get(), payload_size, data, size);
  if (ZSTD_isError(got)) throw InputError(source, std::string("zstd depth: ") + ZSTD_getErrorName(got));
  if (got != payload_size) throw InputError(source, "zstd depth: decoded size differs from the announced size");
  const std::uint32_t table_size = std::uint32_t(payload[0]) | (std::uint32_t(payload[1]) << 8) |
                                   (std::uint32_t(payload[2]) << 16) | (std::uint32_t(payload[3]) << 24);
  if (table_size > 65535 || 4 + 2 * std::size_t(table_size) + n > payload_size)
    throw InputError(source, "zstd depth: value table larger than the data");
  std::vector<std::uint16_t> table(table_size);
  std::uint32_t value = 0;
  for (std::uint32_t k = 0; k < table_size; ++k) {
    const std::uint32_t d = std::uint32_t(payload[4 + 2 * k] | (payload[5 + 2 * k] << 8));
    value += d;
    if (d == 0 || value > 65535) throw InputError(source, "zstd depth: value table not strictly increasing");
    table[k] = std::uint16_t(value);
  }
  const std::uint8_t* valid = payload + 4 + 2 * std::size_t(table_size);
  std::vector<std::uint32_t> row_valid_count(std::size_t(height), 0);
  std::size_t m = 0;
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* row_valid = valid + std::size_t(y) * width;
    std::uint32_t count = 0;
    std::uint8_t bits = 0;  // any byte other than 0 or 1 sets a bit above the lowest
    for (int x = 0; x < width; ++x) {
      count += row_valid[x];
      bits |= row_valid[x];
    }
    if (bits > 1) throw InputError(source, "zstd depth: corrupt hole mask");
    row_valid_count[std::size_t(y)] = count;
    m += count;
  }
  if (4 + 2 * std::size_t(table_size) + n + 2 * m != payload_size || (m > 0 && table_size == 0))
    throw InputError(source, "zstd depth: residual count does not match the hole mask");
  const RankTable ranks_to_depth{table.data(), table_size};
  const std::unique_ptr<std::uint16_t[]> ranks(new std::uint16_t[n]);
  const std::uint8_t* low = valid + n;
  const std::uint8_t* high = low + m;
  std::size_t k = 0;  // the next row's first residual
  std::int32_t last = 0;
  const auto row_cursor = [&](int y) {
    const std::size_t o = std::size_t(y) * width;
    RankRow c{ranks.get() + o, valid + o, nullptr, nullptr, pixels + o, low + k, high + k, last};
    if (y > 0) {
      c.above = c.ranks - width;
      c.above_valid = c.valid - width;
    }
    k += row_valid_count[std::size_t(y)];
    return c;
  };
  const auto fail = [&] { throw InputError(source, "zstd depth: value rank outside the table"); };
  for (int y = 0; y < height;) {
    RankRow a = row_cursor(y);
    // Row y+1 goes beside row y, one pixel behind it, unless its first valid pixel has no valid
    // pixel above: its prediction is then the last rank of row y, known only at that row's end.
    const std::uint8_t* next_valid = a.valid + width;
    const void* first = y + 1 < height ? std::memchr(next_valid, 1, std::size_t(width)) : nullptr;
    const bool paired = y + 1 < height && (!first || a.valid[static_cast<const std::uint8_t*>(first) - next_valid]);
    if (!paired) {
      for (int x = 0; x < width; ++x)
        if (!decode_rank(a, x, ranks_to_depth)) fail();
      last = a.last;
      ++y;
      continue;
    }
    RankRow b = row_cursor(y + 1);
    if (!decode_rank(a, 0, ranks_to_depth)) fail();
    for (int x = 1; x < width; ++x) {
      if (!decode_rank(a, x, ranks_to_depth)) fail();
      if (!decode_rank(b, x - 1, ranks_to_depth)) fail();
    }
    if (!decode_rank(b, width - 1, ranks_to_depth)) fail();
    last = first ? b.last : a.last;
    y += 2;
  }
}

}  // namespace cslam::depth_codec
