#pragma once
// Procedural textured images (multi-scale noise, random shapes, lines and text) used to train the
// vocabulary beyond one real room and as fixtures in tests. Deterministic for a given seed.
#include <cstdint>

#include <opencv2/core.hpp>

namespace cslam {

struct ProceduralImageConfig {
  int width = 640;
  int height = 480;
  int shapes = 120;  // filled/outlined rectangles, circles, ellipses, polygons
  int lines = 40;
  int texts = 12;
  double noise_sigma = 4;  // per-pixel sensor-like noise added at the end
};

// A CV_8UC1 image; the same (seed, config) always gives the same image.
cv::Mat procedural_image(std::uint64_t seed, const ProceduralImageConfig& config = {});

// A view of a planar textured `scene` through a virtual camera: the scene rectangle centred at
// (cx, cy) (scene pixels), rotated by angle_deg and scaled by zoom (>1 = closer), rendered into
// a width x height image (bilinear, border replicated).
cv::Mat render_view(const cv::Mat& scene, double cx, double cy, double angle_deg, double zoom, int width = 640,
                    int height = 480);

}  // namespace cslam
