#include "file_decode_bench.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <turbojpeg.h>

#include "codec/image_codec.h"
#include "codec/jpeg_decode.h"
#include "codec/png16_decode.h"
#include "core/error.h"
#include "cpu_stopwatch.h"
#include "core/stats.h"

namespace cslam {

namespace {

struct Sample {
  std::string path;
  Bytes bytes;  // the file's bytes, for the paths that decode from memory (the wire)
  int width = 0, height = 0;
};

struct Method {
  std::string name;
  bool colour = true;
  std::function<cv::Mat(const Sample&)> decode;
};

struct Result {
  std::vector<double> ms;
  int differing = 0;    // images whose pixels differ from the reference path's
  double max_abs = 0;   // largest per-pixel difference
  double mean_abs = 0;  // mean absolute difference per channel value, averaged over images
};

Bytes read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open");
  return Bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// TurboJPEG with other flags than decode_jpeg_bgr's, to measure what the faster, inexact modes
// (fast integer DCT, plain instead of "fancy" chroma upsampling) would gain and change.
cv::Mat turbojpeg_bgr(const Sample& s, int flags) {
  thread_local tjhandle tj = tjInitDecompress();
  cv::Mat out(s.height, s.width, CV_8UC3);
  if (tjDecompress2(tj, s.bytes.data(), static_cast<unsigned long>(s.bytes.size()), out.data, s.width, int(out.step[0]),
                    s.height, TJPF_BGR, flags) != 0)
    throw InputError(s.path, tjGetErrorStr2(tj));
  return out;
}

bool is_png(const std::string& path) { return path.size() >= 4 && path.compare(path.size() - 4, 4, ".png") == 0; }

std::vector<Method> methods() {
  std::vector<Method> m;
  // Colour. The first one is the reference the others are compared with.
  m.push_back(
      {"imread (load_rgbd before)", true, [](const Sample& s) { return cv::imread(s.path, cv::IMREAD_COLOR); }});
  m.push_back({"load_colour_image (load_rgbd)", true, [](const Sample& s) { return load_colour_image(s.path); }});
  m.push_back({"imdecode (from memory)", true, [](const Sample& s) {
                 return cv::imdecode(s.bytes, cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
               }});
  m.push_back({"decode_rgb (wire)", true, [](const Sample& s) {
                 const RgbCodec c = is_png(s.path) ? RgbCodec::kPng : RgbCodec::kJpeg;
                 return decode_rgb(c, s.bytes.data(), s.bytes.size(), s.width, s.height, s.path);
               }});
  m.push_back({"decode_jpeg_bgr (from memory)", true, [](const Sample& s) {
                 return decode_jpeg_bgr(s.bytes.data(), s.bytes.size(), s.path, s.width, s.height);
               }});
  m.push_back({"turbojpeg fast DCT", true, [](const Sample& s) { return turbojpeg_bgr(s, TJFLAG_FASTDCT); }});
  m.push_back(
      {"turbojpeg fast upsampling", true, [](const Sample& s) { return turbojpeg_bgr(s, TJFLAG_FASTUPSAMPLE); }});
  m.push_back({"turbojpeg fast DCT + upsampling", true,
               [](const Sample& s) { return turbojpeg_bgr(s, TJFLAG_FASTDCT | TJFLAG_FASTUPSAMPLE); }});
  // Depth.
  m.push_back(
      {"imread (load_rgbd before)", false, [](const Sample& s) { return cv::imread(s.path, cv::IMREAD_ANYDEPTH); }});
  m.push_back({"load_depth_image (load_rgbd)", false, [](const Sample& s) { return load_depth_image(s.path); }});
  m.push_back(
      {"imdecode (from memory)", false, [](const Sample& s) { return cv::imdecode(s.bytes, cv::IMREAD_ANYDEPTH); }});
  m.push_back({"decode_png16_gray (from memory)", false, [](const Sample& s) {
                 cv::Mat out;
                 std::string why;
                 if (!decode_png16_gray(s.bytes.data(), s.bytes.size(), out, &why)) throw InputError(s.path, why);
                 return out;
               }});
  m.push_back({"decode_depth png (wire)", false, [](const Sample& s) {
                 return decode_depth(DepthCodec::kPng, s.bytes.data(), s.bytes.size(), s.width, s.height, s.path);
               }});
  return m;
}

std::vector<Sample> load_samples(const std::vector<TimedFile>& files, int n, int imread_flags) {
  std::vector<Sample> out;
  for (int i = 0; i < n && i < int(files.size()); ++i) {
    Sample s;
    s.path = files[std::size_t(i)].path;
    s.bytes = read_bytes(s.path);
    const cv::Mat im = cv::imread(s.path, imread_flags);
    if (im.empty()) throw InputError(s.path, "cannot decode");
    s.width = im.cols;
    s.height = im.rows;
    out.push_back(std::move(s));
  }
  return out;
}

}  // namespace

void run_file_decode_bench(const TumDataset& ds, const FileDecodeBenchOptions& options) {
  const std::vector<Sample> colour = load_samples(ds.rgb, options.files, cv::IMREAD_COLOR);
  const std::vector<Sample> depth = load_samples(ds.depth, options.files, cv::IMREAD_ANYDEPTH);
  const std::vector<Method> ms = methods();
  std::vector<Result> results(ms.size());
  for (int pass = 0; pass < options.repeat; ++pass)
    for (bool is_colour : {true, false}) {
      const std::vector<Sample>& samples = is_colour ? colour : depth;
      for (const Sample& s : samples) {
        cv::Mat reference;
        for (std::size_t k = 0; k < ms.size(); ++k) {
          if (ms[k].colour != is_colour) continue;
          CpuStopwatch t;
          const cv::Mat out = ms[k].decode(s);
          results[k].ms.push_back(t.ms());
          if (pass > 0) continue;
          if (reference.empty()) {
            reference = out;
            continue;
          }
          const bool same_shape = out.size() == reference.size() && out.type() == reference.type();
          const double max_abs = same_shape ? cv::norm(out, reference, cv::NORM_INF) : 1e9;
          if (max_abs > 0) ++results[k].differing;
          results[k].max_abs = std::max(results[k].max_abs, max_abs);
          if (same_shape)
            results[k].mean_abs +=
                cv::norm(out, reference, cv::NORM_L1) / double(out.total() * out.channels()) / double(samples.size());
        }
      }
    }
  std::printf(
      "decoding the dataset's own files: first %zu colour (%s) and %zu depth images, %d passes;\n"
      "thread CPU ms per image, median (min-max); 'differ' = images whose pixels differ from the first row\n\n",
      colour.size(), colour.empty() ? "-" : colour.front().path.substr(colour.front().path.rfind('.')).c_str(),
      depth.size(), options.repeat);
  std::printf("%-6s %-34s %9s %20s %8s %8s %9s\n", "image", "path", "median", "min-max", "differ", "max|d|", "mean|d|");
  for (std::size_t k = 0; k < ms.size(); ++k) {
    const Summary s = summarize(results[k].ms);
    char range[48];
    std::snprintf(range, sizeof range, "%.2f-%.2f", s.min, s.max);
    std::printf("%-6s %-34s %9.2f %20s %8d %8.0f %9.4f\n", ms[k].colour ? "colour" : "depth", ms[k].name.c_str(),
                s.median, range, results[k].differing, results[k].max_abs, results[k].mean_abs);
  }
}

}  // namespace cslam
