#include "io/tum_dataset.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>

#include "codec/codec_plugins.h"
#include "codec/jpeg_decode.h"
#include "codec/png16_decode.h"
#include "codec/png_rgb8_decode.h"
#include "core/error.h"
#include "io/text_table.h"

namespace fs = std::filesystem;

namespace cslam {

namespace {

// One read() of the whole file (an istreambuf_iterator copy costs ~0.15 ms for a 40 KB JPEG).
// Throws InputError(path, error) if it is not a readable regular file.
std::vector<std::uint8_t> read_file_bytes(const std::string& path, const char* error) {
  std::error_code ec;
  const bool regular = fs::is_regular_file(path, ec);
  const std::uintmax_t size = regular ? fs::file_size(path, ec) : 0;
  std::ifstream in(path, std::ios::binary);
  if (!regular || ec || !in) throw InputError(path, error);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
  if (!in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(size))) throw InputError(path, error);
  return bytes;
}

std::vector<TimedFile> read_file_list(const std::string& root, const std::string& name) {
  const std::string path = (fs::path(root) / name).string();
  std::vector<TimedFile> out;
  for_each_text_row(path, [&](int line, const std::vector<std::string>& tok) {
    if (tok.size() != 2)
      throw InputError(path, line, "expected 'timestamp path', got " + std::to_string(tok.size()) + " values");
    TimedFile f;
    f.timestamp = parse_double(tok[0], path, line, "timestamp");
    f.path = (fs::path(root) / tok[1]).string();
    if (!out.empty() && f.timestamp <= out.back().timestamp) throw InputError(path, line, "timestamps must increase");
    out.push_back(f);
  });
  return out;
}

}  // namespace

std::vector<std::pair<int, int>> associate_timestamps(const std::vector<double>& a, const std::vector<double>& b,
                                                      double max_dt) {
  // Candidate pairs within max_dt, accepted greedily by increasing |dt|; both lists are sorted,
  // so a window scan finds the candidates.
  struct Cand {
    double dt;
    int i, j;
  };
  std::vector<Cand> cands;
  size_t start = 0;
  for (int i = 0; i < int(a.size()); ++i) {
    while (start < b.size() && b[start] < a[i] - max_dt) ++start;
    for (size_t j = start; j < b.size() && b[j] <= a[i] + max_dt; ++j)
      cands.push_back({std::abs(a[i] - b[j]), i, int(j)});
  }
  std::sort(cands.begin(), cands.end(), [](const Cand& x, const Cand& y) {
    return x.dt != y.dt ? x.dt < y.dt : (x.i != y.i ? x.i < y.i : x.j < y.j);
  });
  std::vector<char> used_a(a.size(), 0), used_b(b.size(), 0);
  std::vector<std::pair<int, int>> out;
  for (const auto& c : cands) {
    if (used_a[c.i] || used_b[c.j]) continue;
    used_a[c.i] = used_b[c.j] = 1;
    out.emplace_back(c.i, c.j);
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<std::pair<int, int>> associate_nearest(const std::vector<double>& a, const std::vector<double>& b,
                                                   double max_dt) {
  std::vector<std::pair<int, int>> out;
  std::size_t j = 0;  // first b not before a[i] (both lists sorted)
  for (int i = 0; i < int(a.size()); ++i) {
    while (j < b.size() && b[j] < a[i]) ++j;
    int best = -1;
    double best_dt = max_dt;
    if (j < b.size() && b[j] - a[i] <= best_dt) {
      best = int(j);
      best_dt = b[j] - a[i];
    }
    if (j > 0 && a[i] - b[j - 1] <= best_dt && (best < 0 || a[i] - b[j - 1] < best_dt)) best = int(j - 1);
    if (best >= 0) out.emplace_back(i, best);
  }
  return out;
}

Association parse_association(const std::string& text) {
  if (text == "nearest") return Association::kNearest;
  if (text == "unique") return Association::kUnique;
  throw ConfigError("association '" + text + "' must be nearest or unique");
}

TumDataset open_tum_dataset(const std::string& root, double max_dt, Association association) {
  if (!fs::is_directory(root)) throw InputError(root, "dataset folder not found");
  TumDataset ds;
  ds.root = root;
  ds.rgb = read_file_list(root, "rgb.txt");
  ds.depth = read_file_list(root, "depth.txt");
  std::vector<double> ta, tb;
  for (const auto& f : ds.rgb) ta.push_back(f.timestamp);
  for (const auto& f : ds.depth) tb.push_back(f.timestamp);
  const auto pairs =
      association == Association::kNearest ? associate_nearest(ta, tb, max_dt) : associate_timestamps(ta, tb, max_dt);
  for (const auto& [i, j] : pairs) {
    RgbdPair p;
    p.rgb_time = ds.rgb[i].timestamp;
    p.depth_time = ds.depth[j].timestamp;
    p.rgb_path = ds.rgb[i].path;
    p.depth_path = ds.depth[j].path;
    p.index = int(ds.pairs.size());
    ds.pairs.push_back(p);
  }
  const fs::path gt = fs::path(root) / "groundtruth.txt";
  if (fs::exists(gt)) ds.groundtruth = read_tum_trajectory(gt.string());
  return ds;
}

std::vector<RgbdPair> select_range(const std::vector<RgbdPair>& pairs, int first, int last) {
  if (first < 1 || last > int(pairs.size()) || first > last)
    throw std::out_of_range("frame range [" + std::to_string(first) + ", " + std::to_string(last) +
                            "] is outside [1, " + std::to_string(pairs.size()) + "]");
  return std::vector<RgbdPair>(pairs.begin() + (first - 1), pairs.begin() + last);
}

std::pair<int, int> parse_range(const std::string& text, int count) {
  const auto colon = text.find(':');
  if (colon == std::string::npos) throw ConfigError("range '" + text + "' must be 'a:b' (1-based, inclusive)");
  auto parse = [&](const std::string& s, int fallback) {
    if (s.empty()) return fallback;
    size_t used = 0;
    int v = 0;
    try {
      v = std::stoi(s, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != s.size()) throw ConfigError("range '" + text + "' is not 'a:b' with whole numbers");
    return v;
  };
  return {parse(text.substr(0, colon), 1), parse(text.substr(colon + 1), count)};
}

cv::Mat load_colour_image(const std::string& path) {
  const std::vector<std::uint8_t> bytes = read_file_bytes(path, "cannot read RGB image");
  if (looks_like_jpeg(bytes.data(), bytes.size())) return decode_jpeg_bgr(bytes.data(), bytes.size(), path);
  cv::Mat out;
  // An 8-bit RGB PNG (TUM's published colour images): libdeflate and SSE4.1, the same pixels as
  // OpenCV in 2.3 instead of 4.6 ms (OpenCV's default PNG settings) or 1.9 instead of 7.6 ms
  // (zlib level 6, adaptive filters) per 640x480 image.
  if (decode_png_rgb8(bytes.data(), bytes.size(), out)) return out;
  // Any other file, or a damaged one: OpenCV decodes the same bytes as cv::imread did.
  if (!bytes.empty()) out = image_io().imdecode(cv::Mat(bytes), cv::IMREAD_COLOR);
  if (out.empty()) throw InputError(path, "cannot read RGB image");
  return out;
}

cv::Mat load_depth_image(const std::string& path) {
  const std::vector<std::uint8_t> bytes = read_file_bytes(path, "cannot read depth image");
  cv::Mat depth;
  if (decode_png16_gray(bytes.data(), bytes.size(), depth)) return depth;
  // Any other file, or a damaged one: OpenCV decodes the same bytes as cv::imread did.
  if (!bytes.empty()) depth = image_io().imdecode(cv::Mat(bytes), cv::IMREAD_ANYDEPTH);
  if (depth.empty()) throw InputError(path, "cannot read depth image");
  if (depth.type() != CV_16UC1) throw InputError(path, "depth image must be 16-bit single channel");
  return depth;
}

RgbdImages load_rgbd(const RgbdPair& pair) {
  RgbdImages im;
  im.bgr = load_colour_image(pair.rgb_path);
  im.depth = load_depth_image(pair.depth_path);
  return im;
}

}  // namespace cslam
