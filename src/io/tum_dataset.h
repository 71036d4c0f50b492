#pragma once
// Reader for the TUM RGB-D layout: rgb.txt, depth.txt ("timestamp relative/path", '#' comments),
// optional groundtruth.txt, images as PNG or JPEG (RGB) and 16-bit PNG (depth).
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "io/trajectory_io.h"

namespace cslam {

struct TimedFile {
  double timestamp = 0;
  std::string path;  // absolute (root joined with the listed relative path)
};

struct RgbdPair {
  double rgb_time = 0, depth_time = 0;
  std::string rgb_path, depth_path;
  // Index of the pair in the full associated list, 0-based.
  int index = 0;
};

struct TumDataset {
  std::string root;
  std::vector<TimedFile> rgb, depth;
  std::vector<RgbdPair> pairs;            // associated RGB-D pairs, time-ordered
  std::optional<Trajectory> groundtruth;  // if groundtruth.txt exists
};

// How colour and depth images are paired.
enum class Association {
  // Every colour image takes the depth image nearest in time (|dt| <= max_dt); a depth image may
  // serve two colour images. The camera delivered every colour frame: when the sensor dropped a
  // depth frame, the colour frame is still there, and leaving it out would double the motion
  // between two frames exactly where the camera moves fastest.
  kNearest,
  // Each image used at most once, greedy by smallest difference (TUM's associate.py).
  kUnique,
};
// Parses "nearest" / "unique"; throws ConfigError otherwise.
Association parse_association(const std::string& text);

// Reads the lists and associates RGB and depth by timestamp. Throws InputError on a missing
// folder/file or a malformed line.
TumDataset open_tum_dataset(const std::string& root, double max_dt = 0.02,
                            Association association = Association::kNearest);

// Associates two timestamp lists one to one; returns index pairs (i in a, j in b), sorted by a's time.
std::vector<std::pair<int, int>> associate_timestamps(const std::vector<double>& a, const std::vector<double>& b,
                                                      double max_dt);
// Every a takes the nearest b within max_dt (a b may be taken more than once); sorted by a's time.
std::vector<std::pair<int, int>> associate_nearest(const std::vector<double>& a, const std::vector<double>& b,
                                                   double max_dt);

// Frames [first, last], 1-based inclusive as in the paper; throws std::out_of_range if empty or
// outside [1, pairs.size()].
std::vector<RgbdPair> select_range(const std::vector<RgbdPair>& pairs, int first, int last);
// Parses "a:b" (also "a:" = to the end); throws ConfigError on malformed text.
std::pair<int, int> parse_range(const std::string& text, int count);

struct RgbdImages {
  cv::Mat bgr;    // CV_8UC3
  cv::Mat depth;  // CV_16UC1 raw values
};
// Loads both images; throws InputError naming the file if unreadable or of the wrong type.
RgbdImages load_rgbd(const RgbdPair& pair);
// The two halves of load_rgbd. Colour: a JPEG (recognised by its first bytes) is decoded by
// codec/jpeg_decode.h, straight to BGR and bit-identical to cv::imread; a corrupt or truncated one
// is an InputError. Anything else (PNG) goes through OpenCV. Depth: a plain 16-bit greyscale PNG
// (TUM's depth images) is decoded by codec/png16_decode.h (libdeflate), bit-identical to
// cv::imread; any other file, and any PNG it does not fully accept, goes to OpenCV (cv::imdecode
// of the same bytes: cv::imread's decoder and errors). Unreadable, undecodable or not 16-bit
// single-channel: InputError.
cv::Mat load_colour_image(const std::string& path);
cv::Mat load_depth_image(const std::string& path);

}  // namespace cslam
