// cslam-bench-codec: encoded size and encode/decode time of every RGB and depth codec on a
// TUM-layout dataset (default: the shared tum_fr1_rpy), plus the totals per codec pair; then the
// time to decode the dataset's own image files by each path (file_decode_bench.h). With
// --decode-png-dir, also the time to decode a folder's colour PNGs by each path (TUM's published
// colour images are 8-bit RGB PNGs; the shared copies are JPEGs).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <iterator>
#include <map>
#include <utility>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "codec/image_codec.h"
#include "codec/png_rgb8_decode.h"
#include "core/cli.h"
#include "core/error.h"
#include "core/stopwatch.h"
#include "cpu_stopwatch.h"
#include "eval/stats.h"
#include "file_decode_bench.h"
#include "io/tum_dataset.h"

namespace {

using cslam::CpuStopwatch;

struct Result {
  std::vector<double> kb, encode_ms, decode_ms, psnr;
  bool lossless = true;
};

double psnr(const cv::Mat& a, const cv::Mat& b) {
  const double mse = cv::norm(a, b, cv::NORM_L2SQR) / double(a.total() * a.channels());
  return mse == 0 ? 99.0 : 10.0 * std::log10(255.0 * 255.0 / mse);
}

std::string fmt(const cslam::Summary& s, int precision = 2) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.*f (%.*f-%.*f)", precision, s.median, precision, s.min, precision, s.max);
  return buf;
}

// --decode-png-dir: thread-CPU ms per image of decoding the first `files` (0: all) colour PNGs of
// `dir` (sorted by name) by each path, over `repeat` passes, and whether each path's pixels equal
// cv::imdecode's. decode_png_rgb8 alone refuses what it does not handle (counted, not timed).
void run_colour_png_bench(const std::string& dir, int files, int repeat) {
  namespace fs = std::filesystem;
  std::vector<std::string> paths;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file() && e.path().extension() == ".png") paths.push_back(e.path().string());
  std::sort(paths.begin(), paths.end());
  if (files > 0 && int(paths.size()) > files) paths.resize(std::size_t(files));
  if (paths.empty()) throw cslam::InputError(dir, "no .png files");
  std::vector<cslam::Bytes> bytes;
  for (const std::string& p : paths) {
    std::ifstream in(p, std::ios::binary);
    bytes.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  struct Path {
    std::string name;
    std::function<cv::Mat(std::size_t)> decode;  // empty Mat: refused
    std::vector<double> ms{};
    int differing = 0, refused = 0;
  };
  const auto path = [](std::string name, std::function<cv::Mat(std::size_t)> decode) {
    Path p;
    p.name = std::move(name);
    p.decode = std::move(decode);
    return p;
  };
  std::vector<Path> methods = {
      path("imdecode IMREAD_COLOR (from memory)",
           [&](std::size_t i) { return cv::imdecode(bytes[i], cv::IMREAD_COLOR); }),
      path("decode_png_rgb8 (from memory)",
           [&](std::size_t i) {
             cv::Mat out;
             cslam::decode_png_rgb8(bytes[i].data(), bytes[i].size(), out);
             return out;
           }),
      path("imread IMREAD_COLOR (file)", [&](std::size_t i) { return cv::imread(paths[i], cv::IMREAD_COLOR); }),
      path("load_colour_image (file)", [&](std::size_t i) { return cslam::load_colour_image(paths[i]); }),
  };
  double kb = 0;
  for (const auto& b : bytes) kb += double(b.size()) / 1000.0 / double(bytes.size());
  for (int pass = 0; pass < repeat; ++pass)
    for (std::size_t i = 0; i < paths.size(); ++i) {
      cv::Mat reference;
      for (Path& m : methods) {
        CpuStopwatch t;
        const cv::Mat out = m.decode(i);
        const double ms = t.ms();
        if (out.empty()) {
          if (pass == 0) ++m.refused;
          continue;
        }
        m.ms.push_back(ms);
        if (pass > 0) continue;
        if (reference.empty()) {
          reference = out;
        } else if (out.size() != reference.size() || out.type() != reference.type() ||
                   cv::norm(out, reference, cv::NORM_INF) != 0) {
          ++m.differing;
        }
      }
    }
  std::printf("decoding colour PNGs: %zu files of %s (mean %.1f KB), %d passes;\n"
              "thread CPU ms per image, median (min-max); 'differ' = images whose pixels differ from the first row\n\n",
              paths.size(), dir.c_str(), kb, repeat);
  std::printf("%-36s %9s %16s %8s %8s\n", "path", "median", "min-max", "differ", "refused");
  for (const Path& m : methods) {
    if (m.ms.empty()) {
      std::printf("%-36s %9s %16s %8d %8d\n", m.name.c_str(), "-", "-", m.differing, m.refused);
      continue;
    }
    const cslam::Summary s = cslam::summarize(m.ms);
    char range[48];
    std::snprintf(range, sizeof range, "%.2f-%.2f", s.min, s.max);
    std::printf("%-36s %9.2f %16s %8d %8d\n", m.name.c_str(), s.median, range, m.differing, m.refused);
  }
}

int run(int argc, char** argv) {
  cslam::CliArgs cli("cslam-bench-codec", "Sizes and times of the image codecs on a TUM-layout dataset.");
  cli.option("dataset", "TUM-layout folder", std::string(CSLAM_SHARED_DATA_DIR) + "/tum_fr1_rpy")
      .option("frames", "number of frames, evenly spaced over the sequence (0 = all)", "100")
      .option("jpeg-qualities", "comma-separated JPEG qualities to measure", "75,90,95")
      .option("decode-files", "decode the first N colour and depth files of the dataset by each path (0 = skip)", "100")
      .option("decode-repeat", "passes over those files", "3")
      .option("decode-png-dir",
              "also decode the first --decode-files colour PNGs (*.png) of this folder by each path (cv::imdecode, "
              "decode_png_rgb8, cv::imread, load_colour_image; --decode-files 0: all of them); with --decode-only, "
              "only that table",
              "")
      .flag("decode-only", "only the file-decoding table, not the codec round trips");
  if (!cli.parse(argc, argv)) return 0;
  if (!cli.get("decode-png-dir").empty()) {
    run_colour_png_bench(cli.get("decode-png-dir"), cli.get_int("decode-files"),
                         std::max(1, cli.get_int("decode-repeat")));
    if (cli.flag_set("decode-only")) return 0;
    std::printf("\n");
  }
  const cslam::TumDataset ds = cslam::open_tum_dataset(cli.get("dataset"));
  cslam::FileDecodeBenchOptions decode_options;
  decode_options.files = cli.get_int("decode-files");
  decode_options.repeat = std::max(1, cli.get_int("decode-repeat"));
  if (cli.flag_set("decode-only")) {
    cslam::run_file_decode_bench(ds, decode_options);
    return 0;
  }
  int n = cli.get_int("frames");
  if (n <= 0 || n > int(ds.pairs.size())) n = int(ds.pairs.size());
  std::vector<int> qualities;
  {
    std::string q = cli.get("jpeg-qualities");
    for (std::size_t p = 0; p < q.size();) {
      std::size_t c = q.find(',', p);
      qualities.push_back(std::stoi(q.substr(p, c - p)));
      p = c == std::string::npos ? q.size() : c + 1;
    }
  }
  struct RgbVariant { std::string name; cslam::CodecOptions opt; };
  std::vector<RgbVariant> rgb_variants;
  cslam::CodecOptions o;
  o.rgb = cslam::RgbCodec::kRaw; rgb_variants.push_back({"raw", o});
  for (int q : qualities) { o.rgb = cslam::RgbCodec::kJpeg; o.jpeg_quality = q; rgb_variants.push_back({"jpeg" + std::to_string(q), o}); }
  o.rgb = cslam::RgbCodec::kPng; rgb_variants.push_back({"png", o});
  std::vector<std::pair<std::string, cslam::CodecOptions>> depth_variants;
  for (auto d : {cslam::DepthCodec::kRaw, cslam::DepthCodec::kPng, cslam::DepthCodec::kRvl, cslam::DepthCodec::kZstdDelta}) {
    cslam::CodecOptions od;
    od.depth = d;
    depth_variants.push_back({cslam::to_string(d), od});
  }
  cslam::CodecOptions z3; z3.depth = cslam::DepthCodec::kZstdDelta; z3.zstd_level = 3;
  depth_variants.push_back({"zstd-l3", z3});

  std::map<std::string, Result> rgb_results, depth_results;
  for (int k = 0; k < n; ++k) {
    const auto& pair = ds.pairs[std::size_t(k) * ds.pairs.size() / std::size_t(n)];
    const cslam::RgbdImages im = cslam::load_rgbd(pair);
    for (const auto& v : rgb_variants) {
      Result& r = rgb_results[v.name];
      CpuStopwatch t;
      const cslam::Bytes bytes = cslam::encode_rgb(im.bgr, v.opt);
      r.encode_ms.push_back(t.ms());
      t.reset();
      const cv::Mat back = cslam::decode_rgb(v.opt.rgb, bytes.data(), bytes.size(), im.bgr.cols, im.bgr.rows, "bench");
      r.decode_ms.push_back(t.ms());
      r.kb.push_back(bytes.size() / 1000.0);
      r.psnr.push_back(psnr(im.bgr, back));
    }
    for (const auto& [name, opt] : depth_variants) {
      Result& r = depth_results[name];
      CpuStopwatch t;
      const cslam::Bytes bytes = cslam::encode_depth(im.depth, opt);
      r.encode_ms.push_back(t.ms());
      t.reset();
      const cv::Mat back = cslam::decode_depth(opt.depth, bytes.data(), bytes.size(), im.depth.cols, im.depth.rows, "bench");
      r.decode_ms.push_back(t.ms());
      r.kb.push_back(bytes.size() / 1000.0);
      if (cv::norm(im.depth, back, cv::NORM_INF) != 0) r.lossless = false;
    }
  }
  std::printf("%d frames of %s (640x480); median (min-max); times are thread CPU ms\n\n", n, cli.get("dataset").c_str());
  std::printf("%-10s %10s %24s %24s %24s %s\n", "rgb", "mean KB", "KB", "encode ms", "decode ms", "PSNR dB (median)");
  for (const auto& v : rgb_variants) {
    const Result& r = rgb_results[v.name];
    std::printf("%-10s %10.1f %24s %24s %24s %.1f\n", v.name.c_str(), cslam::summarize(r.kb).mean,
                fmt(cslam::summarize(r.kb), 1).c_str(), fmt(cslam::summarize(r.encode_ms)).c_str(),
                fmt(cslam::summarize(r.decode_ms)).c_str(), cslam::summarize(r.psnr).median);
  }
  std::printf("\n%-10s %10s %24s %24s %24s %s\n", "depth", "mean KB", "KB", "encode ms", "decode ms", "lossless");
  for (const auto& [name, opt] : depth_variants) {
    const Result& r = depth_results[name];
    std::printf("%-10s %10.1f %24s %24s %24s %s\n", name.c_str(), cslam::summarize(r.kb).mean,
                fmt(cslam::summarize(r.kb), 1).c_str(), fmt(cslam::summarize(r.encode_ms)).c_str(),
                fmt(cslam::summarize(r.decode_ms)).c_str(), r.lossless ? "yes" : "NO");
  }
  std::printf("\n%-20s %10s %12s %16s %16s\n", "pair", "mean KB", "MB/s @30Hz", "encode ms (med)", "decode ms (med)");
  for (const auto& v : rgb_variants)
    for (const auto& [name, opt] : depth_variants) {
      const Result& a = rgb_results[v.name];
      const Result& b = depth_results[name];
      const double kb = cslam::summarize(a.kb).mean + cslam::summarize(b.kb).mean;
      std::printf("%-20s %10.1f %12.2f %16.2f %16.2f\n", (v.name + "+" + name).c_str(), kb, kb * 30 / 1000.0,
                  cslam::summarize(a.encode_ms).median + cslam::summarize(b.encode_ms).median,
                  cslam::summarize(a.decode_ms).median + cslam::summarize(b.decode_ms).median);
    }
  if (decode_options.files > 0) {
    std::printf("\n");
    cslam::run_file_decode_bench(ds, decode_options);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return cslam::run_main("cslam-bench-codec", argc, argv, run); }
