// cslam-test-codec-tool: the C++ codecs (src/codec) on files, so the Python client's codecs can be
// checked byte for byte against them (test_python_codecs.py).
//   encode-rgb  jpeg|png|raw|h264-intra QUALITY IN.png OUT.bin   (QUALITY: the CRF for h264-intra)
//   encode-depth zstd|png|raw LEVEL IN.png OUT.bin
//   decode-depth zstd|png|raw WIDTH HEIGHT IN.bin OUT.png     (16-bit PNG)
//   subsample-depth S IN.png OUT.png                          (16-bit PNG, codec/depth_subsample.h)
//   encode-h264 WIDTH HEIGHT CRF PRESET TUNE KEY_INTERVAL FRAME_RATE FORCED IN.raw OUT.bin
//       IN.raw: frames of WIDTH x HEIGHT BGR8, back to back; FORCED: comma-separated frame
//       indices to force as key frames, or '-'. OUT.bin: the packets back to back (each packet's
//       header gives its length).
//   decode-h264 WIDTH HEIGHT IN.bin OUT.raw
//       IN.bin: packets back to back, decoded in order by one H264Decoder; OUT.raw: the BGR8
//       frames back to back. Any packet the decoder refuses is an error (exit 1).
#include <algorithm>
#include <cstdint>
#include <fstream>
#include <iostream>
#include <iterator>
#include <set>
#include <sstream>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "codec/image_encoder.h"
#include "codec/depth_subsample.h"
#include "codec/image_codec.h"
#include "codec/video_codec.h"

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

std::set<int> parse_indices(const std::string& list) {
  std::set<int> out;
  if (list == "-") return out;
  std::istringstream in(list);
  for (std::string item; std::getline(in, item, ',');) out.insert(std::stoi(item));
  return out;
}

// argv: WIDTH HEIGHT CRF PRESET TUNE KEY_INTERVAL FRAME_RATE FORCED IN.raw OUT.bin
void encode_h264(char** argv) {
  const int width = std::stoi(argv[0]), height = std::stoi(argv[1]);
  cslam::video::H264Options o;
  o.crf = std::stoi(argv[2]);
  o.preset = argv[3];
  o.tune = argv[4];
  o.key_interval = std::stoi(argv[5]);
  o.frame_rate = std::stoi(argv[6]);
  const std::set<int> forced = parse_indices(argv[7]);
  cslam::Bytes frames = read_file(argv[8]);
  const std::size_t frame_bytes = std::size_t(width) * std::size_t(height) * 3;
  if (frame_bytes == 0 || frames.size() % frame_bytes != 0)
    throw std::runtime_error(std::string(argv[8]) + " is not a whole number of " + std::to_string(width) + "x" +
                             std::to_string(height) + " BGR8 frames");
  cslam::video::H264Encoder encoder(width, height, o);
  cslam::Bytes out;
  for (std::size_t i = 0; i * frame_bytes < frames.size(); ++i) {
    const cv::Mat bgr(height, width, CV_8UC3, frames.data() + i * frame_bytes);
    const cslam::Bytes packet = encoder.encode(bgr, forced.count(int(i)) > 0);
    out.insert(out.end(), packet.begin(), packet.end());
  }
  write_file(argv[9], out);
}

// argv: WIDTH HEIGHT IN.bin OUT.raw
void decode_h264(char** argv) {
  const int width = std::stoi(argv[0]), height = std::stoi(argv[1]);
  const cslam::Bytes packets = read_file(argv[2]);
  cslam::video::H264Decoder decoder(width, height);
  cslam::Bytes out;
  for (std::size_t at = 0; at < packets.size();) {
    std::size_t size = packets.size() - at;
    if (size >= cslam::video::kH264HeaderBytes) {
      const std::uint8_t* n = packets.data() + at + 8;
      size = std::min(size, cslam::video::kH264HeaderBytes + (std::size_t(n[0]) | std::size_t(n[1]) << 8 |
                                                              std::size_t(n[2]) << 16 | std::size_t(n[3]) << 24));
    }
    const cv::Mat bgr = decoder.decode(packets.data() + at, size, argv[2]);
    out.insert(out.end(), bgr.data, bgr.data + bgr.total() * bgr.elemSize());
    at += size;
  }
  write_file(argv[3], out);
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string cmd = argc > 1 ? argv[1] : "";
    cslam::CodecOptions o;
    if (cmd == "encode-rgb" && argc == 6) {
      o.rgb = cslam::parse_rgb_codec(argv[2]);
      (o.rgb == cslam::RgbCodec::kH264Intra ? o.h264_intra_crf : o.jpeg_quality) = std::stoi(argv[3]);
      write_file(argv[5], cslam::ImageEncoder(o).rgb(cv::imread(argv[4], cv::IMREAD_COLOR)));
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
    if (cmd == "subsample-depth" && argc == 5) {
      const cv::Mat coarse = cslam::subsample_depth(cv::imread(argv[3], cv::IMREAD_ANYDEPTH), std::stoi(argv[2]));
      return cv::imwrite(argv[4], coarse) ? 0 : 1;
    }
    if (cmd == "encode-h264" && argc == 12) {
      encode_h264(argv + 2);
      return 0;
    }
    if (cmd == "decode-h264" && argc == 6) {
      decode_h264(argv + 2);
      return 0;
    }
    std::cerr << "usage: see the comment at the top of tests/python/codec_tool.cpp\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "codec_tool: " << e.what() << "\n";
    return 1;
  }
}
