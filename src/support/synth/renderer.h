#pragma once
// CPU renderer for the synthetic scene: per-face rasterisation with an exact per-pixel
// ray-plane depth (z-buffer), then a texture lookup (mip-mapped, bilinear) in the baked textures.
// Output as a Kinect/TUM frame: BGR CV_8UC3 and raw depth CV_16UC1 (camera z * depth_factor,
// 0 = no measurement). Optional degradations: depth noise growing with z^2, no depth at grazing
// angles, image noise, motion blur. Deterministic: noise comes from a per-pixel hash of the seed.
#include <cstdint>

#include <opencv2/core.hpp>

#include "geometry/camera.h"
#include "geometry/se3.h"
#include "support/synth/scene.h"

namespace cslam::synth {

struct Degradation {
  bool enabled = false;
  double depth_noise_coeff = 1.4e-3;  // sigma_z = coeff * z^2 (metres), Kinect-like
  double grazing_angle_deg = 78.0;    // no depth where the ray meets the surface flatter than this
  double image_noise_sigma = 2.0;     // grey levels, per channel
  int blur_samples = 3;               // renders averaged along the motion (<= 1: no blur)
  double blur_exposure = 0.4;         // share of the inter-frame motion covered by the exposure
};

struct RenderOptions {
  double min_depth = 0.3, max_depth = 6.0;  // depth outside [min, max] is written as 0
  double near_clip = 0.05;                  // geometry closer than this is not drawn
  int threads = 1;                          // row bands rendered in parallel
  Degradation degradation;
};

struct RenderedFrame {
  cv::Mat bgr;    // CV_8UC3
  cv::Mat depth;  // CV_16UC1 raw, camera.depth_factor per metre
};

class Renderer {
 public:
  // Keeps a reference to the scene (it must outlive the renderer). Throws ConfigError if the camera
  // is invalid or has distortion (only undistorted pinhole cameras are rendered).
  Renderer(const Scene& scene, const PinholeCamera& camera, RenderOptions options = {});

  // The view from T_world_cam. noise_seed selects the noise pattern (used only with degradations).
  RenderedFrame render(const SE3& T_world_cam, std::uint64_t noise_seed = 0) const;
  // As render(), with motion blur (if degradations are enabled) along the motion from the
  // previous frame's pose; the exposure ends at T_world_cam.
  RenderedFrame render_moving(const SE3& T_world_cam_prev, const SE3& T_world_cam, std::uint64_t noise_seed) const;

  const PinholeCamera& camera() const { return camera_; }
  const RenderOptions& options() const { return options_; }

 private:
  struct Pass;
  void render_pass(const SE3& T_world_cam, std::uint64_t noise_seed, bool depth_noise, bool image_noise, cv::Mat& bgr,
                   cv::Mat* depth) const;

  const Scene& scene_;
  PinholeCamera camera_;
  RenderOptions options_;
};

}  // namespace cslam::synth
