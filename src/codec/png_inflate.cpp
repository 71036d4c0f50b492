#include "codec/png_inflate.h"

#include <libdeflate.h>

#include <cstring>
#include <memory>
#include <vector>

#include "codec/image_codec.h"

namespace cslam::png_detail {

namespace {

// libpng refuses (fatally) any chunk longer than PNG_USER_CHUNK_MALLOC_MAX (8,000,000 in Debian
// 12's build) unless it is an IDAT within the image's size; such files are left to it.
constexpr std::uint32_t kMaxChunkLength = 8000000;
// Scratch buffers larger than this are released after the image instead of kept for the next.
constexpr std::size_t kKeepScratchBytes = std::size_t(32) << 20;

struct DecompressorDeleter {
  void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
};

// Per thread: a libdeflate_decompressor must not be used by two threads at once, and keeping the
// buffers avoids allocating ~0.7 MB (depth) or ~0.9 MB (colour) per 640x480 image.
struct ThreadState {
  std::unique_ptr<libdeflate_decompressor, DecompressorDeleter> inflater;
  std::vector<std::uint8_t> idat;  // the IDAT chunks' data, when there is more than one
  std::vector<std::uint8_t> rows;  // inflated image data: per row a filter byte and the row's bytes
};

ThreadState& thread_state() {
  thread_local ThreadState state;
  return state;
}

std::uint32_t be32(const std::uint8_t* p) {
  return (std::uint32_t(p[0]) << 24) | (std::uint32_t(p[1]) << 16) | (std::uint32_t(p[2]) << 8) | p[3];
}

bool is_letter(std::uint8_t c) { return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z'); }

bool type_is(const std::uint8_t* type, const char* name) { return std::memcmp(type, name, 4) == 0; }

// Ancillary chunks libpng only stores (or checks and drops) and OpenCV 4.6 does not apply to a
// 16-bit grey or 8-bit RGB image: it sets no gamma, background, shift or colour-space transform,
// so gAMA, cHRM, sRGB, sBIT and bKGD change no pixel (tests/codec/test_png_rgb8_decode.cpp checks
// this against cv::imdecode). tRNS (an RGB image with it decodes to 4 channels), eXIf (OpenCV
// applies its orientation), the APNG chunks, compressed text, ICC profiles, sPLT, hIST and
// unknown chunks go to OpenCV.
bool ignorable_ancillary(const std::uint8_t* type) {
  static const char* kIgnorable[] = {"gAMA", "cHRM", "sRGB", "sBIT", "bKGD", "pHYs", "tIME", "tEXt"};
  for (const char* name : kIgnorable)
    if (type_is(type, name)) return true;
  return false;
}

bool fail(std::string* why, const std::string& reason) {
  if (why) *why = reason;
  return false;
}

}  // namespace

InflatedPng::~InflatedPng() {
  ThreadState& st = thread_state();
  if (st.rows.capacity() > kKeepScratchBytes) std::vector<std::uint8_t>().swap(st.rows);
  if (st.idat.capacity() > kKeepScratchBytes) std::vector<std::uint8_t>().swap(st.idat);
}

bool inflate_png(const std::uint8_t* d, std::size_t size, const PngFormat& format, InflatedPng& png, std::string* why) {
  static const std::uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (d == nullptr || size < 8 || std::memcmp(d, kSignature, 8) != 0) return fail(why, "not a PNG");
  // IHDR: first, 13 bytes, its CRC right.
  if (size < 8 + 12 + 13 || be32(d + 8) != 13 || !type_is(d + 12, "IHDR"))
    return fail(why, "no IHDR chunk of 13 bytes first");
  if (libdeflate_crc32(0, d + 12, 4 + 13) != be32(d + 29)) return fail(why, "IHDR CRC mismatch");
  const std::uint32_t w = be32(d + 16), h = be32(d + 20);
  const int bit_depth = d[24], colour_type = d[25], compression = d[26], filter = d[27], interlace = d[28];
  if (bit_depth != format.bit_depth || colour_type != format.colour_type || interlace != 0)
    return fail(why, std::string("not a non-interlaced ") + format.description + " PNG (depth " +
                         std::to_string(bit_depth) + ", colour type " + std::to_string(colour_type) + ", interlace " +
                         std::to_string(interlace) + ")");
  if (compression != 0 || filter != 0) return fail(why, "invalid compression or filter method in IHDR");
  if (w == 0 || h == 0 || w > std::uint32_t(kMaxImageSide) || h > std::uint32_t(kMaxImageSide))
    return fail(why, "size " + std::to_string(w) + "x" + std::to_string(h) + " out of range");
  const std::size_t row_bytes = std::size_t(format.bytes_per_pixel) * w;
  const std::size_t stride = 1 + row_bytes;
  const std::size_t inflated_size = std::size_t(h) * stride;  // <= 8192 * (1 + 8 * 8192): no overflow

  // The other chunks, up to IEND: lengths inside the buffer, valid types, CRCs; IDATs consecutive.
  ThreadState& st = thread_state();
  // More compressed data than even fixed Huffman codes need for this image (9 bits per literal at
  // most, stored blocks 5 bytes per 64 kB): not from an encoder. It also bounds the one call to
  // libdeflate, which cannot be interrupted: a stream of empty blocks with their own code tables is
  // the slowest input per byte (about 50 ms per MB on this project's VM: 51 ms at the cap of a
  // 640x480 colour frame), so the decoder's time is bounded by the image size a peer announced.
  const std::size_t max_idat_size = inflated_size + inflated_size / 8 + 1024;
  const std::uint8_t* idat = nullptr;  // the image data, contiguous
  std::size_t idat_size = 0;
  int idat_chunks = 0;
  bool idat_ended = false, seen_iend = false;
  std::size_t pos = 8 + 12 + 13;
  while (!seen_iend) {
    if (size - pos < 12) return fail(why, "truncated (no IEND)");
    const std::uint32_t length = be32(d + pos);
    const std::uint8_t* type = d + pos + 4;
    const std::uint8_t* body = d + pos + 8;
    if (length > size - pos - 12) return fail(why, "chunk runs past the end of the data");
    if (length > kMaxChunkLength) return fail(why, "chunk longer than libpng's limit");
    if (!is_letter(type[0]) || !is_letter(type[1]) || !is_letter(type[2]) || !is_letter(type[3]))
      return fail(why, "invalid chunk type");
    const std::string name(reinterpret_cast<const char*>(type), 4);
    if (libdeflate_crc32(0, type, 4 + std::size_t(length)) != be32(body + length))
      return fail(why, name + " CRC mismatch");
    if (name == "IDAT") {
      if (idat_ended) return fail(why, "IDAT chunks not consecutive");
      if (length > max_idat_size - idat_size) return fail(why, "more image data than the image size allows");
      if (++idat_chunks == 1) {
        idat = body;
        idat_size = length;
      } else {
        if (idat_chunks == 2) st.idat.assign(idat, idat + idat_size);
        st.idat.insert(st.idat.end(), body, body + length);
        idat = st.idat.data();
        idat_size = st.idat.size();
      }
    } else {
      if (idat_chunks > 0) idat_ended = true;
      if (name == "IEND") {
        if (length != 0) return fail(why, "IEND not empty");
        seen_iend = true;
      } else if (!(type[0] & 0x20) || !ignorable_ancillary(type)) {  // bit 5 clear: critical
        return fail(why, "chunk " + name + " left to OpenCV");
      }
    }
    pos += 12 + std::size_t(length);
  }
  if (idat_chunks == 0 || idat_size < 2) return fail(why, "no image data");
  // libpng lets zlib use the window the stream's header declares; libdeflate always allows 32 KB.
  // A smaller declared window is only safe when the whole image data fits in it (libpng's
  // encoder declares one for small images, and then it always does).
  const int window_log = (idat[0] >> 4) + 8;
  if (window_log < 15 && inflated_size > (std::size_t(1) << window_log))
    return fail(why, "zlib window smaller than the image data");

  if (!st.inflater) st.inflater.reset(libdeflate_alloc_decompressor());
  if (!st.inflater) return fail(why, "cannot allocate a libdeflate decompressor");
  st.rows.resize(inflated_size);
  std::size_t used = 0;
  // Exactly inflated_size bytes (fewer: SHORT_OUTPUT, more: INSUFFICIENT_SPACE), Adler-32 checked.
  const libdeflate_result rc =
      libdeflate_zlib_decompress_ex(st.inflater.get(), idat, idat_size, st.rows.data(), inflated_size, &used, nullptr);
  if (rc != LIBDEFLATE_SUCCESS) return fail(why, "inflate failed (libdeflate result " + std::to_string(int(rc)) + ")");
  if (used != idat_size) return fail(why, "data after the end of the zlib stream");
  for (std::uint32_t y = 0; y < h; ++y) {
    const std::uint8_t filter_type = st.rows[std::size_t(y) * stride];
    if (filter_type > 4)
      return fail(why, "bad filter type " + std::to_string(int(filter_type)) + " in row " + std::to_string(y));
  }
  png.width = int(w);
  png.height = int(h);
  png.row_bytes = row_bytes;
  png.stride = stride;
  png.rows = st.rows.data();
  return true;
}

}  // namespace cslam::png_detail
