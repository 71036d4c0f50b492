#include "codec/png16_decode.h"

#include <libdeflate.h>

#include <algorithm>
#include <cstring>
#include <memory>
#include <vector>

#include "codec/image_codec.h"

#if defined(__SSE4_1__)
#include <smmintrin.h>
#endif

namespace cslam {

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
// buffers avoids allocating ~0.7 MB per 640x480 image.
struct ThreadState {
  std::unique_ptr<libdeflate_decompressor, DecompressorDeleter> inflater;
  std::vector<std::uint8_t> idat;  // the IDAT chunks' data, when there is more than one
  std::vector<std::uint8_t> rows;  // inflated image data: per row a filter byte and 2 * width bytes
};

ThreadState& thread_state() {
  thread_local ThreadState state;
  return state;
}

// Releases the thread's buffers after an unusually large image, on every way out.
struct TrimScratch {
  ThreadState& st;
  ~TrimScratch() {
    if (st.rows.capacity() > kKeepScratchBytes) std::vector<std::uint8_t>().swap(st.rows);
    if (st.idat.capacity() > kKeepScratchBytes) std::vector<std::uint8_t>().swap(st.idat);
  }
};

bool fail(std::string* why, const std::string& reason) {
  if (why) *why = reason;
  return false;
}

std::uint32_t be32(const std::uint8_t* p) {
  return (std::uint32_t(p[0]) << 24) | (std::uint32_t(p[1]) << 16) | (std::uint32_t(p[2]) << 8) | p[3];
}

bool is_letter(std::uint8_t c) { return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z'); }

bool type_is(const std::uint8_t* type, const char* name) { return std::memcmp(type, name, 4) == 0; }

// Ancillary chunks libpng only stores (or checks and drops) and OpenCV 4.6 does not apply to a
// 16-bit grey image. tRNS, eXIf (OpenCV applies its orientation), the APNG chunks, compressed
// text and ICC profiles, and unknown chunks go to OpenCV.
bool ignorable_ancillary(const std::uint8_t* type) {
  static const char* kIgnorable[] = {"gAMA", "cHRM", "sRGB", "sBIT", "bKGD", "pHYs", "tIME", "tEXt"};
  for (const char* name : kIgnorable)
    if (type_is(type, name)) return true;
  return false;
}

// Undoing the row filters, bpp = 2: a byte's "left" neighbour is 2 bytes back, so the high and
// low bytes of the pixels form two independent chains. Scalar version, in place: the fallback
// without SSE4.1 and the tests' second opinion on the vector version.
void unfilter_sub(std::uint8_t* cur, std::size_t n) {
  std::uint8_t a0 = cur[0], a1 = cur[1];
  for (std::size_t i = 2; i < n; i += 2) {
    a0 = std::uint8_t(cur[i] + a0);
    a1 = std::uint8_t(cur[i + 1] + a1);
    cur[i] = a0;
    cur[i + 1] = a1;
  }
}

void unfilter_up(std::uint8_t* __restrict cur, const std::uint8_t* __restrict prev, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) cur[i] = std::uint8_t(cur[i] + prev[i]);
}

void unfilter_average(std::uint8_t* __restrict cur, const std::uint8_t* __restrict prev, std::size_t n) {
  std::uint8_t a0 = std::uint8_t(cur[0] + (prev[0] >> 1)), a1 = std::uint8_t(cur[1] + (prev[1] >> 1));
  cur[0] = a0;
  cur[1] = a1;
  for (std::size_t i = 2; i < n; i += 2) {
    a0 = std::uint8_t(cur[i] + ((a0 + prev[i]) >> 1));
    a1 = std::uint8_t(cur[i + 1] + ((a1 + prev[i + 1]) >> 1));
    cur[i] = a0;
    cur[i + 1] = a1;
  }
}

void unfilter_paeth(std::uint8_t* __restrict cur, const std::uint8_t* __restrict prev, std::size_t n) {
  // First pixel: no left neighbour (a = c = 0), the predictor is the byte above.
  cur[0] = std::uint8_t(cur[0] + prev[0]);
  cur[1] = std::uint8_t(cur[1] + prev[1]);
  int a0 = cur[0], a1 = cur[1];
  for (std::size_t i = 2; i < n; i += 2) {
    a0 = std::uint8_t(cur[i] + png16_detail::paeth(a0, prev[i], prev[i - 2]));
    a1 = std::uint8_t(cur[i + 1] + png16_detail::paeth(a1, prev[i + 1], prev[i - 1]));
    cur[i] = std::uint8_t(a0);
    cur[i + 1] = std::uint8_t(a1);
  }
}

void unfilter_rows_scalar(std::uint8_t* rows, int width, int height, cv::Mat& out) {
  const std::size_t n = 2 * std::size_t(width);
  const std::vector<std::uint8_t> zeros(n, 0);
  const std::uint8_t* prev = zeros.data();
  for (int y = 0; y < height; ++y) {
    std::uint8_t* cur = rows + std::size_t(y) * (n + 1) + 1;
    switch (cur[-1]) {
      case 1: unfilter_sub(cur, n); break;
      case 2: unfilter_up(cur, prev, n); break;
      case 3: unfilter_average(cur, prev, n); break;
      case 4: unfilter_paeth(cur, prev, n); break;
      default: break;
    }
    std::uint16_t* dst = out.ptr<std::uint16_t>(y);
    for (int x = 0; x < width; ++x) dst[x] = std::uint16_t((cur[2 * x] << 8) | cur[2 * x + 1]);
    prev = cur;
  }
}

#if defined(__SSE4_1__)
// Four rows at once. Row r of a band sits in 16-bit lanes 2r (high byte) and 2r + 1 (low byte)
// and runs one pixel behind row r - 1, so its bytes "above" and "above-left" are row r - 1's
// results of the previous two steps (a lane shift, no memory) and the eight byte chains advance
// together. Each lane computes all predictors and keeps its row's: one kernel for every filter.
// Results go straight to the output as host-order uint16; row 0 reads the row above the band
// from there.
struct Band {
  const std::uint8_t* cur[4];  // filtered bytes of the band's rows
  std::uint16_t* dst[4];       // their output rows
  const std::uint16_t* above;  // the decoded row above the band
  int rows, width;
  __m128i sub, up, average, paeth;  // per-lane masks of the rows' filter types
};

inline std::uint16_t load_u16(const std::uint8_t* p) {
  std::uint16_t v;
  std::memcpy(&v, p, 2);
  return v;
}

// Step s: row r at pixel s - r. Masked steps leave out the lanes outside their row (band start
// and end, missing rows); their results are zero, which is what "left" and "above-left" of a
// row's first pixel must read.
template <bool kMasked>
inline void band_step(const Band& band, int s, __m128i& res, __m128i& prev_b) {
  const auto valid = [&](int r) { return !kMasked || (r < band.rows && s - r >= 0 && s - r < band.width); };
  __m128i xw = _mm_setzero_si128();
  if (valid(0)) xw = _mm_insert_epi16(xw, load_u16(band.cur[0] + 2 * s), 0);
  if (valid(1)) xw = _mm_insert_epi16(xw, load_u16(band.cur[1] + 2 * (s - 1)), 1);
  if (valid(2)) xw = _mm_insert_epi16(xw, load_u16(band.cur[2] + 2 * (s - 2)), 2);
  if (valid(3)) xw = _mm_insert_epi16(xw, load_u16(band.cur[3] + 2 * (s - 3)), 3);
  const __m128i x = _mm_cvtepu8_epi16(xw);
  const int above = valid(0) ? band.above[s] : 0;
  const __m128i a = res;
  const __m128i b = _mm_or_si128(_mm_slli_si128(res, 4), _mm_cvtsi32_si128((above >> 8) | ((above & 0xff) << 16)));
  const __m128i c = prev_b;
  const __m128i lo = _mm_min_epi16(a, b), hi = _mm_max_epi16(a, b);
  const __m128i t = _mm_sub_epi16(_mm_sub_epi16(_mm_add_epi16(c, _mm_add_epi16(c, c)), a), b);
  const __m128i lo_or_c = _mm_blendv_epi8(lo, c, _mm_cmpgt_epi16(hi, t));
  const __m128i paeth = _mm_blendv_epi8(hi, lo_or_c, _mm_cmpgt_epi16(t, lo));
  const __m128i average = _mm_srli_epi16(_mm_add_epi16(a, b), 1);
  const __m128i pred = _mm_or_si128(_mm_or_si128(_mm_and_si128(a, band.sub), _mm_and_si128(b, band.up)),
                                    _mm_or_si128(_mm_and_si128(average, band.average), _mm_and_si128(paeth, band.paeth)));
  res = _mm_and_si128(_mm_add_epi16(x, pred), _mm_set1_epi16(0xff));
  if (kMasked)
    res = _mm_and_si128(res, _mm_set_epi16(short(-valid(3)), short(-valid(3)), short(-valid(2)), short(-valid(2)),
                                           short(-valid(1)), short(-valid(1)), short(-valid(0)), short(-valid(0))));
  prev_b = b;
  // 32-bit lane r holds high | low << 16; its low 16 bits become high << 8 | low.
  const __m128i v = _mm_or_si128(_mm_slli_epi32(res, 8), _mm_srli_epi32(res, 16));
  if (valid(0)) band.dst[0][s] = std::uint16_t(_mm_extract_epi16(v, 0));
  if (valid(1)) band.dst[1][s - 1] = std::uint16_t(_mm_extract_epi16(v, 2));
  if (valid(2)) band.dst[2][s - 2] = std::uint16_t(_mm_extract_epi16(v, 4));
  if (valid(3)) band.dst[3][s - 3] = std::uint16_t(_mm_extract_epi16(v, 6));
}

void unfilter_rows_simd(const std::uint8_t* rows, int width, int height, cv::Mat& out) {
  const std::size_t stride = 1 + 2 * std::size_t(width);
  const std::vector<std::uint16_t> zeros(std::size_t(width), 0);
  const std::uint16_t* above = zeros.data();
  for (int y0 = 0; y0 < height; y0 += 4) {
    Band band{};
    band.rows = std::min(4, height - y0);
    band.width = width;
    band.above = above;
    std::int16_t masks[4][8] = {};  // sub, up, average, paeth
    for (int r = 0; r < band.rows; ++r) {
      const std::uint8_t* row = rows + std::size_t(y0 + r) * stride;
      band.cur[r] = row + 1;
      band.dst[r] = out.ptr<std::uint16_t>(y0 + r);
      if (row[0] >= 1 && row[0] <= 4) masks[row[0] - 1][2 * r] = masks[row[0] - 1][2 * r + 1] = -1;
    }
    band.sub = _mm_loadu_si128(reinterpret_cast<const __m128i*>(masks[0]));
    band.up = _mm_loadu_si128(reinterpret_cast<const __m128i*>(masks[1]));
    band.average = _mm_loadu_si128(reinterpret_cast<const __m128i*>(masks[2]));
    band.paeth = _mm_loadu_si128(reinterpret_cast<const __m128i*>(masks[3]));
    __m128i res = _mm_setzero_si128(), prev_b = _mm_setzero_si128();
    const int steps = width + band.rows - 1;
    int s = 0;
    if (band.rows == 4) {
      for (; s < std::min(3, steps); ++s) band_step<true>(band, s, res, prev_b);
      for (; s < width; ++s) band_step<false>(band, s, res, prev_b);
    }
    for (; s < steps; ++s) band_step<true>(band, s, res, prev_b);
    above = band.dst[band.rows - 1];
  }
}
#endif

}  // namespace

namespace png16_detail {

void unfilter_rows(std::uint8_t* rows, int width, int height, cv::Mat& out, bool simd) {
#if defined(__SSE4_1__)
  if (simd) return unfilter_rows_simd(rows, width, height, out);
#endif
  unfilter_rows_scalar(rows, width, height, out);
}

}  // namespace png16_detail

bool decode_png16_gray(const std::uint8_t* d, std::size_t size, cv::Mat& out, std::string* why) {
  static const std::uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (d == nullptr || size < 8 || std::memcmp(d, kSignature, 8) != 0) return fail(why, "not a PNG");
  // IHDR: first, 13 bytes, its CRC right.
  if (size < 8 + 12 + 13 || be32(d + 8) != 13 || !type_is(d + 12, "IHDR"))
    return fail(why, "no IHDR chunk of 13 bytes first");
  if (libdeflate_crc32(0, d + 12, 4 + 13) != be32(d + 29)) return fail(why, "IHDR CRC mismatch");
  const std::uint32_t w = be32(d + 16), h = be32(d + 20);
  const int bit_depth = d[24], colour_type = d[25], compression = d[26], filter = d[27], interlace = d[28];
  if (bit_depth != 16 || colour_type != 0 || interlace != 0)
    return fail(why, "not a non-interlaced 16-bit greyscale PNG (depth " + std::to_string(bit_depth) + ", colour type " +
                         std::to_string(colour_type) + ", interlace " + std::to_string(interlace) + ")");
  if (compression != 0 || filter != 0) return fail(why, "invalid compression or filter method in IHDR");
  if (w == 0 || h == 0 || w > std::uint32_t(kMaxImageSide) || h > std::uint32_t(kMaxImageSide))
    return fail(why, "size " + std::to_string(w) + "x" + std::to_string(h) + " out of range");
  const std::size_t row_bytes = 2 * std::size_t(w);
  const std::size_t stride = 1 + row_bytes;
  const std::size_t inflated_size = std::size_t(h) * stride;  // <= 8192 * 16385: no overflow

  // The other chunks, up to IEND: lengths inside the buffer, valid types, CRCs; IDATs consecutive.
  ThreadState& st = thread_state();
  const TrimScratch trim{st};
  // More compressed data than even fixed Huffman codes need for this image: not from an encoder.
  const std::size_t max_idat_size = 2 * inflated_size + 1024;
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
  cv::Mat image(int(h), int(w), CV_16UC1);
  png16_detail::unfilter_rows(st.rows.data(), int(w), int(h), image, true);
  out = image;
  return true;
}

}  // namespace cslam
