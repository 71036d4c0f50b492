#pragma once
// Hostile payloads for the hardening benchmark (cslam-bench-hostile) and the adversarial tests:
// a PNG whose header announces a small image but whose image stream inflates far past it (a
// decompression bomb). Bench code never includes tests/: the payloads live here.
#include <zlib.h>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace cslam::hostile {

inline void put_be32(std::string& out, std::uint32_t v) {
  out += char(v >> 24);
  out += char(v >> 16);
  out += char(v >> 8);
  out += char(v);
}

inline void put_chunk(std::string& out, const char* type, const std::string& body) {
  put_be32(out, std::uint32_t(body.size()));
  const std::string typed = std::string(type, 4) + body;
  out += typed;
  put_be32(out, std::uint32_t(crc32(0, reinterpret_cast<const Bytef*>(typed.data()), uInt(typed.size()))));
}

// An 8-bit PNG of width x height (RGB, or 16-bit grey if depth16) whose zlib stream holds the
// real image rows followed by `extra_bytes` more zero bytes (extra_bytes = 0: a valid PNG).
inline std::string png_bomb(int width, int height, std::size_t extra_bytes, bool depth16 = false) {
  const std::size_t row = 1 + std::size_t(width) * (depth16 ? 2 : 3);
  std::string raw(row * std::size_t(height), '\0');
  for (int y = 0; y < height; ++y)
    for (std::size_t x = 1; x < row; ++x) raw[std::size_t(y) * row + x] = char((x * 7 + std::size_t(y)) & 0xff);
  z_stream z{};
  deflateInit(&z, 9);
  std::string compressed;
  std::vector<unsigned char> out(1 << 16);
  auto pump = [&](const char* data, std::size_t n, int flush) {
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data));
    z.avail_in = uInt(n);
    do {
      z.next_out = out.data();
      z.avail_out = uInt(out.size());
      deflate(&z, flush);
      compressed.append(reinterpret_cast<char*>(out.data()), out.size() - z.avail_out);
    } while (z.avail_out == 0);
  };
  pump(raw.data(), raw.size(), Z_NO_FLUSH);
  const std::string zeros(1 << 20, '\0');
  for (std::size_t left = extra_bytes; left > 0;) {
    const std::size_t n = std::min(left, zeros.size());
    pump(zeros.data(), n, Z_NO_FLUSH);
    left -= n;
  }
  pump(nullptr, 0, Z_FINISH);
  deflateEnd(&z);
  std::string png("\x89PNG\r\n\x1a\n", 8);
  std::string ihdr;
  put_be32(ihdr, std::uint32_t(width));
  put_be32(ihdr, std::uint32_t(height));
  ihdr += char(depth16 ? 16 : 8);
  ihdr += char(depth16 ? 0 : 2);
  ihdr += std::string(3, '\0');
  put_chunk(png, "IHDR", ihdr);
  for (std::size_t pos = 0; pos < compressed.size(); pos += 1 << 16)
    put_chunk(png, "IDAT", compressed.substr(pos, 1 << 16));
  put_chunk(png, "IEND", "");
  return png;
}

}  // namespace cslam::hostile
