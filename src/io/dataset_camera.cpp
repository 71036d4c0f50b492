#include "io/dataset_camera.h"

#include <cctype>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <vector>

#include "core/error.h"
#include "core/log.h"
#include "geometry/camera_io.h"
#include "io/tum_dataset.h"

namespace cslam {

namespace {

bool word_boundary(const std::string& s, std::size_t i) {
  return i == 0 || !std::isalnum(static_cast<unsigned char>(s[i - 1]));
}

// The TUM camera a single path component names, or "".
std::string preset_in(std::string name) {
  for (char& c : name) c = char(std::tolower(static_cast<unsigned char>(c)));
  for (const std::string prefix : {"freiburg", "fr"}) {
    for (std::size_t i = name.find(prefix); i != std::string::npos; i = name.find(prefix, i + 1)) {
      const std::size_t d = i + prefix.size();
      if (!word_boundary(name, i) || d >= name.size()) continue;
      const char n = name[d];
      if (n < '1' || n > '3') continue;
      if (d + 1 < name.size() && std::isdigit(static_cast<unsigned char>(name[d + 1]))) continue;  // fr12: not a camera
      return std::string("tum") + n;
    }
  }
  return "";
}

}  // namespace

std::string tum_preset_from_name(const std::string& path) {
  std::filesystem::path p(path);
  if (p.filename().empty()) p = p.parent_path();  // "dir/"
  for (int up = 0; up < 2 && !p.empty(); ++up, p = p.parent_path()) {
    const std::string preset = preset_in(p.filename().string());
    if (!preset.empty()) return preset;
    if (p == p.parent_path()) break;
  }
  return "";
}

namespace {

// calibration.txt as the ETH3D SLAM benchmark ships it beside its TUM-layout listings: one line
// "fx fy cx cy" of an undistorted pinhole camera, depth 5000 per metre as TUM's. The image size is
// the first colour image's. nullopt (with a warning) if the file says something else.
std::optional<PinholeCamera> calibration_txt(const std::string& dataset_dir, const std::string& path) {
  std::ifstream in(path);
  std::vector<double> v;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream words(line);
    for (double x; words >> x;) v.push_back(x);
    if (!words.eof()) v.clear();  // a word that is not a number
    break;
  }
  if (v.size() != 4 || !(v[0] > 0 && v[1] > 0 && v[2] > 0 && v[3] > 0)) {
    logger("io")->warn("{}: not 'fx fy cx cy' (ETH3D's calibration.txt): ignored", path);
    return std::nullopt;
  }
  PinholeCamera c;
  c.name = "calibration.txt";
  c.fx = v[0];
  c.fy = v[1];
  c.cx = v[2];
  c.cy = v[3];
  const TumDataset ds = open_tum_dataset(dataset_dir);
  if (ds.rgb.empty())
    throw InputError(dataset_dir + "/rgb.txt", "no colour image listed: cannot size the camera of " + path);
  // Read as the frames will be (our JPEG and PNG decoders; OpenCV's plugin only for other formats).
  const cv::Mat first = load_colour_image(ds.rgb.front().path);
  c.width = first.cols;
  c.height = first.rows;
  c.validate();
  return c;
}

DatasetCamera choose(const std::string& dataset_dir, const std::string& choice) {
  DatasetCamera out;
  if (!choice.empty()) {
    out.camera = load_camera(choice);
    out.source = "--camera " + choice;
    return out;
  }
  const auto yaml = std::filesystem::path(dataset_dir) / "camera.yaml";
  if (std::filesystem::exists(yaml)) {
    out.camera = load_camera_file(yaml.string());
    out.source = yaml.string();
    return out;
  }
  const auto calibration = std::filesystem::path(dataset_dir) / "calibration.txt";
  if (std::filesystem::exists(calibration)) {
    if (auto c = calibration_txt(dataset_dir, calibration.string())) {
      out.camera = *c;
      out.source = calibration.string();
      return out;
    }
  }
  const std::string preset = tum_preset_from_name(dataset_dir);
  if (!preset.empty()) {
    out.camera = camera_preset(preset);
    out.source = "folder name '" + dataset_dir + "'";
    return out;
  }
  out.camera = camera_preset("tum1");
  out.source =
      "default: no camera.yaml, no calibration.txt and no TUM camera (freiburg1..3) in the folder name; pass --camera";
  out.guessed = true;
  return out;
}

}  // namespace

DatasetCamera dataset_camera(const std::string& dataset_dir, const std::string& choice) {
  DatasetCamera out = choose(dataset_dir, choice);
  if (out.guessed)
    logger("io")->warn("{}: camera {} ({})", dataset_dir, out.camera.name, out.source);
  else
    logger("io")->info("{}: camera {} ({})", dataset_dir, out.camera.name, out.source);
  return out;
}

}  // namespace cslam
