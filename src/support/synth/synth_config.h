#pragma once
// Everything that defines a synthetic dataset, and the named presets.
#include <string>

#include "geometry/camera.h"
#include "support/synth/renderer.h"
#include "support/synth/scene.h"
#include "support/synth/trajectory_planner.h"

namespace cslam::synth {

struct OutputConfig {
  std::string out_dir;        // OUT: robot_<k>/ (or whole/), scene.ply, scene.json
  bool whole = false;         // one long sequence OUT/whole/ instead of one folder per robot
  bool overwrite = false;     // replace an existing OUT (otherwise an existing OUT is an error)
  int threads = 2;            // frames rendered and written in parallel
  double ply_spacing = 0.01;  // scene.ply sample spacing, metres
  int png_compression = 1;    // zlib level 0-9 (PNG stays lossless)
};

struct SynthConfig {
  std::string preset = "custom";
  SceneConfig scene;
  TrajectoryConfig trajectory;
  RenderOptions render;
  PinholeCamera camera;  // undistorted; see synthetic_camera()
  OutputConfig output;
};

// TUM fr1-like intrinsics without distortion (the "synthetic" camera preset) scaled to width x
// height. Throws ConfigError on a non-positive size.
PinholeCamera synthetic_camera(int width, int height);

// "demo": 3 robots x 300 frames at 640x480, robot 1 closes a loop (the README's demo scene).
// "test-small": 2 robots x 60 frames at 320x240, no loop, for fast tests.
// Throws ConfigError on another name.
SynthConfig synth_preset(const std::string& name);

}  // namespace cslam::synth
