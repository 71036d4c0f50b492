// cslam-bench-codec: encoded size and encode/decode time of every RGB and depth codec on a
// TUM-layout dataset (default: the shared tum_fr1_rpy), plus the totals per codec pair; then the
// time to decode the dataset's own image files by each path (file_decode_bench.h).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>

#include <opencv2/core.hpp>

#include "codec/image_codec.h"
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

int run(int argc, char** argv) {
  cslam::CliArgs cli("cslam-bench-codec", "Sizes and times of the image codecs on a TUM-layout dataset.");
  cli.option("dataset", "TUM-layout folder", std::string(CSLAM_SHARED_DATA_DIR) + "/tum_fr1_rpy")
      .option("frames", "number of frames, evenly spaced over the sequence (0 = all)", "100")
      .option("jpeg-qualities", "comma-separated JPEG qualities to measure", "75,90,95")
      .option("decode-files", "decode the first N colour and depth files of the dataset by each path (0 = skip)", "100")
      .option("decode-repeat", "passes over those files", "3")
      .flag("decode-only", "only the file-decoding table, not the codec round trips");
  if (!cli.parse(argc, argv)) return 0;
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
