// cslam-test-codec-tool: the C++ codecs (src/codec) on files, so the Python client's codecs can be
// checked byte for byte against them (test_python_codecs.py).
//   encode-rgb  jpeg|png|raw QUALITY IN.png OUT.bin
//   encode-depth zstd|png|raw LEVEL IN.png OUT.bin
//   decode-depth zstd|png|raw WIDTH HEIGHT IN.bin OUT.png     (16-bit PNG)
#include <fstream>
#include <iostream>
#include <iterator>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "codec/image_codec.h"

namespace {

cslam::Bytes read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  return cslam::Bytes(std::istreambuf_iterator<char>(in), {});
}

void write_file(const std::string& path, const cslam::Bytes& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path);
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string cmd = argc > 1 ? argv[1] : "";
    cslam::CodecOptions o;
    if (cmd == "encode-rgb" && argc == 6) {
      o.rgb = cslam::parse_rgb_codec(argv[2]);
      o.jpeg_quality = std::stoi(argv[3]);
      write_file(argv[5], cslam::encode_rgb(cv::imread(argv[4], cv::IMREAD_COLOR), o));
      return 0;
    }
    if (cmd == "encode-depth" && argc == 6) {
      o.depth = cslam::parse_depth_codec(argv[2]);
      o.zstd_level = std::stoi(argv[3]);
      write_file(argv[5], cslam::encode_depth(cv::imread(argv[4], cv::IMREAD_ANYDEPTH), o));
      return 0;
    }
    if (cmd == "decode-depth" && argc == 7) {
      const cslam::Bytes data = read_file(argv[5]);
      const cv::Mat depth = cslam::decode_depth(cslam::parse_depth_codec(argv[2]), data.data(), data.size(),
                                                std::stoi(argv[3]), std::stoi(argv[4]), argv[5]);
      return cv::imwrite(argv[6], depth) ? 0 : 1;
    }
    std::cerr << "usage: see the comment at the top of tests/python/codec_tool.cpp\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "codec_tool: " << e.what() << "\n";
    return 1;
  }
}
