#include "codec/depth_codecs.h"

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

std::vector<std::uint8_t> zstd_delta_encode(const std::uint16_t* pixels, int width, int height, int level) {
  const std::size_t n = std::size_t(width) * std::size_t(height);
  std::vector<std::uint8_t> planes(2 * n);
  for (int y = 0; y < height; ++y) {
    const std::uint16_t* row = pixels + std::size_t(y) * width;
    for (int x = 0; x < width; ++x) {
      const std::uint16_t pred = x > 0 ? row[x - 1] : (y > 0 ? row[x - width] : 0);
      const auto residual = std::int16_t(std::uint16_t(row[x] - pred));
      const auto z = std::uint16_t((std::uint16_t(residual) << 1) ^ std::uint16_t(residual >> 15));
      const std::size_t i = std::size_t(y) * width + x;
      planes[i] = std::uint8_t(z & 0xff);
      planes[n + i] = std::uint8_t(z >> 8);
    }
  }
  std::vector<std::uint8_t> out(ZSTD_compressBound(planes.size()));
  const std::size_t written = ZSTD_compress(out.data(), out.size(), planes.data(), planes.size(), level);
  if (ZSTD_isError(written)) throw std::runtime_error(std::string("zstd compression failed: ") + ZSTD_getErrorName(written));
  out.resize(written);
  return out;
}

void zstd_delta_decode(const std::uint8_t* data, std::size_t size, std::uint16_t* pixels, int width, int height,
                       const std::string& source) {
  const std::size_t n = std::size_t(width) * std::size_t(height);
  const unsigned long long announced = ZSTD_getFrameContentSize(data, size);
  if (announced == ZSTD_CONTENTSIZE_ERROR) throw InputError(source, "zstd depth: not a zstd frame");
  if (announced != ZSTD_CONTENTSIZE_UNKNOWN && announced != 2 * n)
    throw InputError(source, "zstd depth: content size " + std::to_string(announced) + " does not match " +
                                 std::to_string(width) + "x" + std::to_string(height));
  std::vector<std::uint8_t> planes(2 * n);
  const std::size_t got = ZSTD_decompress(planes.data(), planes.size(), data, size);
  if (ZSTD_isError(got)) throw InputError(source, std::string("zstd depth: ") + ZSTD_getErrorName(got));
  if (got != planes.size()) throw InputError(source, "zstd depth: decoded size does not match the image size");
  for (int y = 0; y < height; ++y) {
    std::uint16_t* row = pixels + std::size_t(y) * width;
    for (int x = 0; x < width; ++x) {
      const std::size_t i = std::size_t(y) * width + x;
      const std::uint16_t z = std::uint16_t(planes[i] | (planes[n + i] << 8));
      const auto residual = std::uint16_t((z >> 1) ^ std::uint16_t(-(z & 1)));
      const std::uint16_t pred = x > 0 ? row[x - 1] : (y > 0 ? row[x - width] : 0);
      row[x] = std::uint16_t(pred + residual);
    }
  }
}

}  // namespace cslam::depth_codec
