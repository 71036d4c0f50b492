#include "io/dataset_camera.h"

#include <cctype>
#include <filesystem>

#include "core/log.h"
#include "geometry/camera_io.h"

namespace cslam {

namespace {

bool word_boundary(const std::string& s, std::size_t i) { return i == 0 || !std::isalnum(static_cast<unsigned char>(s[i - 1])); }

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
  const std::string preset = tum_preset_from_name(dataset_dir);
  if (!preset.empty()) {
    out.camera = camera_preset(preset);
    out.source = "folder name '" + dataset_dir + "'";
    return out;
  }
  out.camera = camera_preset("tum1");
  out.source = "default: no camera.yaml and no TUM camera (freiburg1..3) in the folder name; pass --camera";
  out.guessed = true;
  return out;
}

}  // namespace

DatasetCamera dataset_camera(const std::string& dataset_dir, const std::string& choice) {
  DatasetCamera out = choose(dataset_dir, choice);
  if (out.guessed) logger("io")->warn("{}: camera {} ({})", dataset_dir, out.camera.name, out.source);
  else logger("io")->info("{}: camera {} ({})", dataset_dir, out.camera.name, out.source);
  return out;
}

}  // namespace cslam
