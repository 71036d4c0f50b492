// cslam-bench-codec: encoded size and encode/decode time of every RGB and depth codec on a
// TUM-layout dataset (default: the shared tum_fr1_rpy), plus the totals per codec pair; then the
// time to decode the dataset's own image files by each path (file_decode_bench.h). With
// --decode-png-dir, also the time to decode a folder's colour PNGs by each path (TUM's published
// colour images are 8-bit RGB PNGs; the shared copies are JPEGs). With --h264, only the H.264
// stream table: every colour image in order through one stream per preset, tune and CRF
// (codec/video_codec.h), with JPEG on the same images beside it.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <iterator>
#include <map>
#include <memory>
#include <utility>

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "codec/image_encoder.h"
#include "codec/image_codec.h"
#include "codec/png_rgb8_decode.h"
#include "codec/video_codec.h"
#include "core/cli.h"
#include "core/error.h"
#include "core/stopwatch.h"
#include "cpu_stopwatch.h"
#include "core/stats.h"
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

std::vector<std::string> split_list(const std::string& text, char separator = ',') {
  std::vector<std::string> items;
  for (std::size_t p = 0; p < text.size();) {
    const std::size_t c = text.find(separator, p);
    items.push_back(text.substr(p, c - p));
    p = c == std::string::npos ? text.size() : c + 1;
  }
  return items;
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
  std::printf(
      "decoding colour PNGs: %zu files of %s (mean %.1f KB), %d passes;\n"
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

// --h264: the dataset's first `frames` colour images (0: all) in order, each through one H.264
// stream per preset x tune x CRF and through JPEG at each quality. Per row: mean KB per frame,
// mean KB of the key frames, PSNR against the image read from the dataset (mean, min),
// thread-CPU ms per frame (median), and on every orb_every-th frame the share of the original's
// ORB features found again in the decoded image (OrbSurvival).
struct H264BenchOptions {
  int frames = 0;
  std::vector<int> crfs, jpeg_qualities;
  std::vector<std::string> presets, tunes;
  int key_interval = 300;
  int orb_every = 5;
};

// OpenCV's ORB with ORB-SLAM's settings (1000 features, 8 levels, factor 1.2, FAST 20): a feature
// of the original survives if the decoded image has one within 2 px whose descriptor is its
// mutual nearest neighbour at Hamming distance <= 50 (ORB-SLAM's TH_LOW).
class OrbSurvival {
 public:
  OrbSurvival() : orb_(cv::ORB::create(1000, 1.2f, 8, 31, 0, 2, cv::ORB::HARRIS_SCORE, 31, 20)) {}
  void set_original(const cv::Mat& bgr) { detect(bgr, kp_, desc_); }
  double kept(const cv::Mat& bgr) const {
    std::vector<cv::KeyPoint> kp;
    cv::Mat desc;
    detect(bgr, kp, desc);
    if (kp_.empty()) return 1.0;
    if (kp.empty()) return 0.0;
    std::vector<cv::DMatch> matches;
    cv::BFMatcher(cv::NORM_HAMMING, true).match(desc_, desc, matches);
    int n = 0;
    for (const cv::DMatch& m : matches)
      if (m.distance <= 50 && cv::norm(kp_[std::size_t(m.queryIdx)].pt - kp[std::size_t(m.trainIdx)].pt) <= 2.0) ++n;
    return double(n) / double(kp_.size());
  }

 private:
  void detect(const cv::Mat& bgr, std::vector<cv::KeyPoint>& kp, cv::Mat& desc) const {
    cv::Mat grey;
    cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
    orb_->detectAndCompute(grey, cv::noArray(), kp, desc);
  }
  cv::Ptr<cv::ORB> orb_;
  std::vector<cv::KeyPoint> kp_;
  cv::Mat desc_;
};

void run_h264_bench(const cslam::TumDataset& ds, const H264BenchOptions& options) {
  namespace video = cslam::video;
  struct Row {
    std::string name;
    std::unique_ptr<video::H264Encoder> encoder;
    std::unique_ptr<video::H264Decoder> decoder;
    cslam::CodecOptions jpeg;  // JPEG rows (no encoder)
    std::vector<double> kb, key_kb, encode_ms, decode_ms, psnr, orb;
  };
  OrbSurvival orb;
  std::vector<Row> rows;
  std::size_t n = ds.rgb.size();
  if (options.frames > 0 && std::size_t(options.frames) < n) n = std::size_t(options.frames);
  if (n == 0) throw cslam::InputError(ds.root, "no colour images");
  for (std::size_t k = 0; k < n; ++k) {
    const cv::Mat bgr = cslam::load_colour_image(ds.rgb[k].path);
    if (rows.empty()) {
      for (const std::string& preset : options.presets)
        for (const std::string& tune : options.tunes)
          for (int crf : options.crfs) {
            video::H264Options o;
            o.crf = crf;
            o.preset = preset;
            o.tune = tune;
            o.key_interval = options.key_interval;
            Row r;
            r.name = "h264 " + preset + " " + tune + " crf" + std::to_string(crf);
            r.encoder = std::make_unique<video::H264Encoder>(bgr.cols, bgr.rows, o);
            r.decoder = std::make_unique<video::H264Decoder>(bgr.cols, bgr.rows);
            rows.push_back(std::move(r));
          }
      for (int q : options.jpeg_qualities) {
        Row r;
        r.name = "jpeg q" + std::to_string(q);
        r.jpeg.rgb = cslam::RgbCodec::kJpeg;
        r.jpeg.jpeg_quality = q;
        rows.push_back(std::move(r));
      }
    }
    const bool orb_frame = options.orb_every > 0 && k % std::size_t(options.orb_every) == 0;
    if (orb_frame) orb.set_original(bgr);
    for (Row& r : rows) {
      CpuStopwatch t;
      const cslam::Bytes bytes = r.encoder ? r.encoder->encode(bgr) : cslam::encode_rgb(bgr, r.jpeg);
      r.encode_ms.push_back(t.ms());
      t.reset();
      const cv::Mat back = r.decoder ? r.decoder->decode(bytes.data(), bytes.size(), "bench")
                                     : cslam::decode_rgb(cslam::RgbCodec::kJpeg, bytes.data(), bytes.size(), bgr.cols,
                                                         bgr.rows, "bench");
      r.decode_ms.push_back(t.ms());
      r.kb.push_back(bytes.size() / 1000.0);
      if (r.encoder && video::is_h264_key_packet(bytes.data(), bytes.size())) r.key_kb.push_back(bytes.size() / 1000.0);
      r.psnr.push_back(psnr(bgr, back));
      if (orb_frame) r.orb.push_back(100.0 * orb.kept(back));
    }
  }
  std::printf(
      "%zu colour images of %s in order, one stream per row (key interval %d); PSNR against the\n"
      "dataset's images; times are thread CPU ms per frame, median; ORB kept: mean %% of the original's\n"
      "ORB features found again (every %d-th frame)\n\n",
      n, ds.root.c_str(), options.key_interval, options.orb_every);
  std::printf("%-36s %8s %8s %11s %9s %9s %9s %10s %10s %6s\n", "colour", "mean KB", "key KB", "MB/s @30Hz",
              "PSNR mean", "PSNR min", "ORB kept", "encode ms", "decode ms", "keys");
  for (const Row& r : rows) {
    const double kb = cslam::summarize(r.kb).mean;
    char key_kb[32] = "-";
    if (!r.key_kb.empty()) std::snprintf(key_kb, sizeof key_kb, "%.1f", cslam::summarize(r.key_kb).mean);
    char orb_kept[32] = "-";
    if (!r.orb.empty()) std::snprintf(orb_kept, sizeof orb_kept, "%.1f", cslam::summarize(r.orb).mean);
    std::printf("%-36s %8.1f %8s %11.2f %9.2f %9.2f %9s %10.2f %10.2f %6s\n", r.name.c_str(), kb, key_kb,
                kb * 30 / 1000.0, cslam::summarize(r.psnr).mean, cslam::summarize(r.psnr).min, orb_kept,
                cslam::summarize(r.encode_ms).median, cslam::summarize(r.decode_ms).median,
                r.encoder ? std::to_string(r.key_kb.size()).c_str() : "all");
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
      .flag("decode-only", "only the file-decoding table, not the codec round trips")
      .flag(
          "h264",
          "only the H.264 table: the first --h264-frames colour images in order, one stream per preset, tune and CRF, "
          "JPEG at --jpeg-qualities on the same images")
      .option("h264-crfs", "comma-separated x264 CRFs for --h264", "16,17,18,20,23,26,28,30,32")
      .option("h264-presets", "comma-separated x264 presets for --h264", "veryfast")
      .option("h264-tunes", "x264 tunes for --h264, separated by ';' (each must include zerolatency)",
              "zerolatency,psnr")
      .option("h264-orb-every", "--h264: ORB survival on every N-th frame (0 = off)", "5")
      .option("h264-key-interval", "frames between key frames for --h264", "300")
      .option("h264-frames", "first N colour images in order for --h264 (0 = all)", "0");
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
  std::vector<int> qualities;
  for (const std::string& q : split_list(cli.get("jpeg-qualities"))) qualities.push_back(std::stoi(q));
  if (cli.flag_set("h264")) {
    H264BenchOptions h;
    h.frames = cli.get_int("h264-frames");
    for (const std::string& c : split_list(cli.get("h264-crfs"))) h.crfs.push_back(std::stoi(c));
    h.presets = split_list(cli.get("h264-presets"));
    h.tunes = split_list(cli.get("h264-tunes"), ';');
    h.orb_every = cli.get_int("h264-orb-every");
    h.key_interval = cli.get_int("h264-key-interval");
    h.jpeg_qualities = qualities;
    run_h264_bench(ds, h);
    return 0;
  }
  int n = cli.get_int("frames");
  if (n <= 0 || n > int(ds.pairs.size())) n = int(ds.pairs.size());
  struct RgbVariant {  // one encoder per variant: the frames form one stream
    std::string name;
    cslam::CodecOptions opt;
    cslam::ImageEncoder encoder{opt};
  };
  std::vector<RgbVariant> rgb_variants;
  cslam::CodecOptions o;
  o.rgb = cslam::RgbCodec::kRaw;
  rgb_variants.push_back({"raw", o});
  for (int q : qualities) {
    o.rgb = cslam::RgbCodec::kJpeg;
    o.jpeg_quality = q;
    rgb_variants.push_back({"jpeg" + std::to_string(q), o});
  }
  o.rgb = cslam::RgbCodec::kPng;
  rgb_variants.push_back({"png", o});
  o.rgb = cslam::RgbCodec::kH264Intra;
  rgb_variants.push_back({"h264-intra" + std::to_string(o.h264_intra_crf), o});
  std::vector<std::pair<std::string, cslam::CodecOptions>> depth_variants;
  for (auto d :
       {cslam::DepthCodec::kRaw, cslam::DepthCodec::kPng, cslam::DepthCodec::kRvl, cslam::DepthCodec::kZstdDelta}) {
    cslam::CodecOptions od;
    od.depth = d;
    depth_variants.push_back({cslam::to_string(d), od});
  }
  cslam::CodecOptions z3;
  z3.depth = cslam::DepthCodec::kZstdDelta;
  z3.zstd_level = 3;
  depth_variants.push_back({"zstd-l3", z3});

  std::map<std::string, Result> rgb_results, depth_results;
  for (int k = 0; k < n; ++k) {
    const auto& pair = ds.pairs[std::size_t(k) * ds.pairs.size() / std::size_t(n)];
    const cslam::RgbdImages im = cslam::load_rgbd(pair);
    for (auto& v : rgb_variants) {
      Result& r = rgb_results[v.name];
      CpuStopwatch t;
      const cslam::Bytes bytes = v.encoder.rgb(im.bgr);
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
      const cv::Mat back =
          cslam::decode_depth(opt.depth, bytes.data(), bytes.size(), im.depth.cols, im.depth.rows, "bench");
      r.decode_ms.push_back(t.ms());
      r.kb.push_back(bytes.size() / 1000.0);
      if (cv::norm(im.depth, back, cv::NORM_INF) != 0) r.lossless = false;
    }
  }
  std::printf("%d frames of %s (640x480); median (min-max); times are thread CPU ms\n\n", n,
              cli.get("dataset").c_str());
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
