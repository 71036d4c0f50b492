#include "support/synth/synth_config.h"

#include "core/error.h"

namespace cslam::synth {

PinholeCamera synthetic_camera(int width, int height) {
  if (width <= 0 || height <= 0)
    throw ConfigError("synth: image size must be positive, got " + std::to_string(width) + "x" +
                      std::to_string(height));
  PinholeCamera c = camera_preset("synthetic");
  const double sx = width / 640.0, sy = height / 480.0;
  c.fx *= sx;
  c.fy *= sy;
  c.cx = (c.cx + 0.5) * sx - 0.5;
  c.cy = (c.cy + 0.5) * sy - 0.5;
  c.width = width;
  c.height = height;
  return c;
}

SynthConfig synth_preset(const std::string& name) {
  SynthConfig c;
  c.preset = name;
  if (name == "demo") {
    c.scene.seed = 1;
    c.scene.furniture = 10;
    c.trajectory.robots = 3;
    c.trajectory.frames = 300;
    c.trajectory.loop = true;
    c.camera = synthetic_camera(640, 480);
  } else if (name == "test-small") {
    c.scene.seed = 7;
    c.scene.furniture = 8;
    c.trajectory.robots = 2;
    c.trajectory.frames = 60;
    c.trajectory.loop = false;
    c.camera = synthetic_camera(320, 240);
  } else {
    throw ConfigError("synth: unknown preset '" + name + "' (use demo or test-small)");
  }
  return c;
}

}  // namespace cslam::synth
