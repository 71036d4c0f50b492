#pragma once
// The camera of a TUM-layout dataset folder, chosen by one rule for every program: what the user
// named; else the folder's camera.yaml; else its calibration.txt ("fx fy cx cy", as the ETH3D SLAM
// benchmark ships its TUM-layout sequences: undistorted, depth 5000 per metre); else the TUM
// camera its name says (the benchmark's folders and bags are named rgbd_dataset_freiburgN_...,
// shortened frN_... by many); else tum1.
// A sequence of another TUM camera run with fr1's intrinsics and distortion loses accuracy
// without any error, so a program says which camera it took and why.
#include <string>

#include "geometry/camera.h"

namespace cslam {

struct DatasetCamera {
  PinholeCamera camera;
  std::string source;    // why this one: "--camera tum2", "camera.yaml", "folder name ...", "default"
  bool guessed = false;  // neither named, nor a camera.yaml, nor a TUM folder name: tum1 by default
};

// `choice`: a preset or a camera file; empty: the rule above. Logs which camera it took and why
// (a warning when it fell back to tum1). Throws ConfigError / InputError as load_camera does.
DatasetCamera dataset_camera(const std::string& dataset_dir, const std::string& choice = "");

// "tum1", "tum2" or "tum3" when the last or second-to-last component of `path` names a TUM
// camera (freiburg1..3 or fr1..3 as a word: rgbd_dataset_freiburg2_xyz, tum_fr1_desk,
// fr3-office.bag), else "".
std::string tum_preset_from_name(const std::string& path);

}  // namespace cslam
