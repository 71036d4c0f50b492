#include "geometry/camera_io.h"

#include <filesystem>
#include <set>

#include <opencv2/core.hpp>

#include "core/error.h"

namespace cslam {

namespace {
const std::set<std::string> kRequired = {"fx", "fy", "cx", "cy", "width", "height"};
const std::set<std::string> kKnown = {
    "name",        "fx", "fy", "cx",    "cy",     "k1",           "k2",
    "p1",          "p2", "k3", "width", "height", "depth_factor", "depth_scale_correction",
    "readout_time"};
}  // namespace

PinholeCamera load_camera_file(const std::string& path) {
  if (!std::filesystem::is_regular_file(path)) throw InputError(path, "camera file not found");
  cv::FileStorage fs;
  try {
    if (!fs.open(path, cv::FileStorage::READ)) throw InputError(path, "cannot open camera file");
  } catch (const cv::Exception&) {
    throw InputError(path, "not a valid YAML/JSON camera file");
  }
  const cv::FileNode root = fs.root();
  if (!root.isMap()) throw InputError(path, "camera file must be a map of keys to values");
  std::set<std::string> seen;
  for (const auto& node : root) {
    const std::string key = node.name();
    if (!kKnown.count(key)) throw InputError(path, "unknown camera key '" + key + "'");
    if (key != "name" && !node.isReal() && !node.isInt())
      throw InputError(path, "camera key '" + key + "' must be a number");
    seen.insert(key);
  }
  for (const auto& key : kRequired)
    if (!seen.count(key)) throw InputError(path, "missing camera key '" + key + "'");
  PinholeCamera c;
  c.name = seen.count("name") ? std::string(root["name"]) : std::filesystem::path(path).stem().string();
  auto num = [&](const char* key, double fallback) { return seen.count(key) ? double(root[key]) : fallback; };
  c.fx = num("fx", c.fx);
  c.fy = num("fy", c.fy);
  c.cx = num("cx", c.cx);
  c.cy = num("cy", c.cy);
  c.dist = {num("k1", 0), num("k2", 0), num("p1", 0), num("p2", 0), num("k3", 0)};
  c.width = int(num("width", c.width));
  c.height = int(num("height", c.height));
  c.depth_factor = num("depth_factor", c.depth_factor);
  c.depth_scale_correction = num("depth_scale_correction", 1.0);
  c.readout_time = num("readout_time", 0.0);  // absent: global shutter
  try {
    c.validate();
  } catch (const ConfigError& e) {
    throw InputError(path, e.what());
  }
  return c;
}

void save_camera_file(const PinholeCamera& c, const std::string& path) {
  cv::FileStorage fs(path, cv::FileStorage::WRITE);
  if (!fs.isOpened()) throw InputError(path, "cannot write camera file");
  fs << "name" << c.name << "fx" << c.fx << "fy" << c.fy << "cx" << c.cx << "cy" << c.cy;
  fs << "k1" << c.dist[0] << "k2" << c.dist[1] << "p1" << c.dist[2] << "p2" << c.dist[3] << "k3" << c.dist[4];
  fs << "width" << c.width << "height" << c.height << "depth_factor" << c.depth_factor;
  fs << "depth_scale_correction" << c.depth_scale_correction << "readout_time" << c.readout_time;
}

PinholeCamera load_camera(const std::string& preset_or_path) {
  if (std::filesystem::exists(preset_or_path)) return load_camera_file(preset_or_path);
  return camera_preset(preset_or_path);
}

}  // namespace cslam
