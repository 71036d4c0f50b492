#include "slam/features/procedural_image.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include <opencv2/imgproc.hpp>

namespace cslam {

cv::Mat procedural_image(std::uint64_t seed, const ProceduralImageConfig& config) {
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ull + 12345);
  auto uni = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  auto uint = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  const int W = config.width, H = config.height;

  // Background: sum of noise octaves (coarse to fine), contrast varying per image.
  cv::Mat acc(H, W, CV_32F, cv::Scalar(0));
  const double contrast = uni(20, 70);
  for (int cell = 128; cell >= 4; cell /= 2) {
    cv::Mat small(std::max(2, H / cell), std::max(2, W / cell), CV_32F);
    for (int r = 0; r < small.rows; ++r)
      for (int c = 0; c < small.cols; ++c) small.at<float>(r, c) = float(std::normal_distribution<double>(0, 1)(rng));
    cv::Mat big;
    cv::resize(small, big, acc.size(), 0, 0, cv::INTER_CUBIC);
    acc += big * (contrast * std::sqrt(cell / 128.0) * uni(0.3, 1.0));
  }
  cv::Mat img;
  acc += uni(80, 170);
  acc.convertTo(img, CV_8U);

  const int max_dim = std::max(W, H);
  for (int i = 0; i < config.shapes; ++i) {
    const cv::Scalar color(uint(0, 255));
    const int thickness = uni(0, 1) < 0.6 ? cv::FILLED : uint(1, 4);
    const cv::Point c(uint(-20, W + 20), uint(-20, H + 20));
    const int size = int(max_dim * std::pow(uni(0, 1), 2.5) * 0.25) + 3;  // many small, few large
    switch (uint(0, 3)) {
      case 0:
        cv::rectangle(img, c, c + cv::Point(uint(3, size), uint(3, size)), color, thickness, cv::LINE_AA);
        break;
      case 1:
        cv::circle(img, c, size / 2 + 2, color, thickness, cv::LINE_AA);
        break;
      case 2:
        cv::ellipse(img, c, cv::Size(size / 2 + 2, uint(2, size / 2 + 2)), uni(0, 180), 0, 360, color, thickness,
                    cv::LINE_AA);
        break;
      default: {
        std::vector<cv::Point> pts;
        const int n = uint(3, 6);
        for (int k = 0; k < n; ++k) pts.push_back(c + cv::Point(uint(-size, size), uint(-size, size)));
        if (thickness == cv::FILLED)
          cv::fillConvexPoly(img, pts, color, cv::LINE_AA);
        else
          cv::polylines(img, pts, true, color, thickness, cv::LINE_AA);
      }
    }
  }
  for (int i = 0; i < config.lines; ++i)
    cv::line(img, cv::Point(uint(0, W), uint(0, H)), cv::Point(uint(0, W), uint(0, H)), cv::Scalar(uint(0, 255)),
             uint(1, 3), cv::LINE_AA);
  static const char* kWords[] = {"cslam", "ORB", "map", "desk", "EXIT", "42", "robot", "lab", "A7", "kf"};
  for (int i = 0; i < config.texts; ++i)
    cv::putText(img, kWords[uint(0, 9)], cv::Point(uint(0, W - 40), uint(20, H)), uint(0, 7), uni(0.5, 2.5),
                cv::Scalar(uint(0, 255)), uint(1, 3), cv::LINE_AA);
  if (uni(0, 1) < 0.5) cv::GaussianBlur(img, img, cv::Size(3, 3), uni(0.5, 1.2));
  if (config.noise_sigma > 0) {
    std::normal_distribution<float> noise(0.0f, float(config.noise_sigma));
    for (int r = 0; r < H; ++r) {
      std::uint8_t* row = img.ptr<std::uint8_t>(r);
      for (int c = 0; c < W; ++c) row[c] = cv::saturate_cast<std::uint8_t>(row[c] + noise(rng));
    }
  }
  return img;
}

cv::Mat render_view(const cv::Mat& scene, double cx, double cy, double angle_deg, double zoom, int width, int height) {
  // Maps output pixel (x,y) -> scene: rotate/scale about the output centre, then move to (cx,cy).
  cv::Mat M = cv::getRotationMatrix2D(cv::Point2f(float(width) / 2, float(height) / 2), angle_deg, 1.0 / zoom);
  M.at<double>(0, 2) += cx - width / 2.0;
  M.at<double>(1, 2) += cy - height / 2.0;
  cv::Mat view;
  cv::warpAffine(scene, view, M, cv::Size(width, height), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                 cv::BORDER_REPLICATE);
  return view;
}

}  // namespace cslam
