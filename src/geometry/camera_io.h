#pragma once
// Camera files: YAML or JSON (read with OpenCV's FileStorage), flat keys:
//   name, fx, fy, cx, cy, k1, k2, p1, p2, k3, width, height, depth_factor, depth_scale_correction
// fx fy cx cy width height are required; others default as in PinholeCamera. Unknown keys are errors.
#include <string>

#include "geometry/camera.h"

namespace cslam {

PinholeCamera load_camera_file(const std::string& path);
void save_camera_file(const PinholeCamera& camera, const std::string& path);
// A preset name or a file path: "tum1", "synthetic", "cam.yaml", ...
PinholeCamera load_camera(const std::string& preset_or_path);

}  // namespace cslam
