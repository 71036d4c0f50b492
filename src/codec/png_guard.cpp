#include "codec/png_guard.h"

#include <zlib.h>

#include <cstring>
#include <vector>

#include "core/error.h"
#include "core/stopwatch.h"

namespace cslam {

namespace {

std::uint32_t be32(const std::uint8_t* p) {
  return (std::uint32_t(p[0]) << 24) | (std::uint32_t(p[1]) << 16) | (std::uint32_t(p[2]) << 8) | p[3];
}

int channels_of(int color_type) {
  switch (color_type) {
    case 0:
      return 1;  // grey
    case 2:
      return 3;  // RGB
    case 3:
      return 1;  // palette
    case 4:
      return 2;  // grey + alpha
    case 6:
      return 4;  // RGBA
    default:
      return 0;
  }
}

bool valid_depth(int color_type, int bit_depth) {
  switch (color_type) {
    case 0:
      return bit_depth == 1 || bit_depth == 2 || bit_depth == 4 || bit_depth == 8 || bit_depth == 16;
    case 3:
      return bit_depth == 1 || bit_depth == 2 || bit_depth == 4 || bit_depth == 8;
    case 2:
    case 4:
    case 6:
      return bit_depth == 8 || bit_depth == 16;
    default:
      return false;
  }
}

std::size_t pass_bytes(std::size_t w, std::size_t h, int bits_per_pixel) {
  if (w == 0 || h == 0) return 0;
  return h * (1 + (w * std::size_t(bits_per_pixel) + 7) / 8);
}

// Chunk types a plain image may carry; everything compressed (zTXt, iTXt, iCCP) is refused.
bool allowed_chunk(const char* type) {
  static const char* kAllowed[] = {"IHDR", "PLTE", "IDAT", "IEND", "tRNS", "gAMA", "cHRM", "sRGB",
                                   "sBIT", "bKGD", "pHYs", "tIME", "tEXt", "hIST", "sPLT", "eXIf"};
  for (const char* a : kAllowed)
    if (std::memcmp(type, a, 4) == 0) return true;
  return false;
}

}  // namespace

std::size_t png_inflated_size(int width, int height, int bit_depth, int color_type, bool interlaced) {
  const int bpp = channels_of(color_type) * bit_depth;
  const std::size_t w = std::size_t(width), h = std::size_t(height);
  if (!interlaced) return pass_bytes(w, h, bpp);
  // Adam7: seven passes with their own (start, step) in x and y.
  static const int kX0[7] = {0, 4, 0, 2, 0, 1, 0}, kDx[7] = {8, 8, 4, 4, 2, 2, 1};
  static const int kY0[7] = {0, 0, 4, 0, 2, 0, 1}, kDy[7] = {8, 8, 8, 4, 4, 2, 2};
  std::size_t total = 0;
  for (int p = 0; p < 7; ++p) {
    const std::size_t pw = w > std::size_t(kX0[p]) ? (w - kX0[p] + kDx[p] - 1) / kDx[p] : 0;
    const std::size_t ph = h > std::size_t(kY0[p]) ? (h - kY0[p] + kDy[p] - 1) / kDy[p] : 0;
    total += pass_bytes(pw, ph, bpp);
  }
  return total;
}

void check_png_stream(const std::uint8_t* d, std::size_t size, const PngLimits& limits, const std::string& source) {
  static const std::uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (size < 33 || std::memcmp(d, kSignature, 8) != 0 || std::memcmp(d + 12, "IHDR", 4) != 0 || be32(d + 8) != 13)
    throw InputError(source, "not a PNG image");
  const std::uint32_t w = be32(d + 16), h = be32(d + 20);
  if (w != std::uint32_t(limits.width) || h != std::uint32_t(limits.height))
    throw InputError(source, "PNG is " + std::to_string(w) + "x" + std::to_string(h) + ", expected " +
                                 std::to_string(limits.width) + "x" + std::to_string(limits.height));
  const int bit_depth = d[24], color_type = d[25], compression = d[26], filter = d[27], interlace = d[28];
  if (!valid_depth(color_type, bit_depth) || compression != 0 || filter != 0 || interlace > 1)
    throw InputError(source, "PNG header is invalid");
  if (limits.depth16_grey && (bit_depth != 16 || color_type != 0))
    throw InputError(source, "depth PNG must be 16-bit grey");
  const std::size_t expected = png_inflated_size(limits.width, limits.height, bit_depth, color_type, interlace == 1);

  z_stream z{};
  if (inflateInit(&z) != Z_OK) throw std::runtime_error("zlib inflateInit failed");
  struct Guard {
    z_stream* z;
    ~Guard() { inflateEnd(z); }
  } guard{&z};
  std::vector<std::uint8_t> scratch(64 * 1024);
  std::size_t produced = 0;
  bool stream_end = false, seen_iend = false;
  const double start_cpu_ms = thread_cpu_ms();
  std::size_t pos = 8;
  while (pos < size && !seen_iend) {
    if (size - pos < 12) throw InputError(source, "PNG truncated");
    const std::uint32_t length = be32(d + pos);
    const char* type = reinterpret_cast<const char*>(d + pos + 4);
    if (length > size - pos - 12) throw InputError(source, "PNG chunk runs past the end");
    if (!allowed_chunk(type)) throw InputError(source, "PNG chunk '" + std::string(type, 4) + "' not accepted");
    const std::uint8_t* body = d + pos + 8;
    if (std::memcmp(type, "IEND", 4) == 0) seen_iend = true;
    if (std::memcmp(type, "IDAT", 4) == 0 && length > 0) {
      if (stream_end) throw InputError(source, "PNG has image data after the end of its stream");
      z.next_in = const_cast<Bytef*>(body);
      z.avail_in = length;
      while (z.avail_in > 0 && !stream_end) {
        z.next_out = scratch.data();
        z.avail_out = uInt(scratch.size());
        const int rc = inflate(&z, Z_NO_FLUSH);
        if (rc != Z_OK && rc != Z_STREAM_END && rc != Z_BUF_ERROR)
          throw InputError(source, std::string("PNG image data corrupt (") + (z.msg ? z.msg : "zlib error") + ")");
        produced += scratch.size() - z.avail_out;
        if (produced > expected)
          throw InputError(source, "PNG image data inflates past the " + std::to_string(expected) +
                                       " bytes its header implies (decompression bomb?)");
        stream_end = rc == Z_STREAM_END;
        if (rc == Z_BUF_ERROR && z.avail_out != 0) break;  // needs the next chunk
        if (limits.time_budget_ms > 0 && thread_cpu_ms() - start_cpu_ms > limits.time_budget_ms)
          throw InputError(source, "PNG image data took longer than the decode budget");
      }
      if (stream_end && z.avail_in > 0) throw InputError(source, "PNG has data after the end of its image stream");
    }
    pos += 12 + length;
  }
  if (!seen_iend) throw InputError(source, "PNG truncated (no IEND)");
  if (!stream_end || produced != expected)
    throw InputError(source,
                     "PNG image data is " + std::to_string(produced) + " bytes, expected " + std::to_string(expected));
}

}  // namespace cslam
