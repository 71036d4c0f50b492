#include "support/synth/texture.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <opencv2/imgproc.hpp>

#include "support/synth/random.h"

namespace cslam::synth {
namespace {

// A saturated colour that is either dark or bright, so shapes stand out from the background.
cv::Scalar contrast_color(Rng& rng) {
  const double hue = rng.uniform(0, 6), sat = rng.uniform(0.2, 1.0);
  const bool bright = rng.chance(0.5);
  const double value = bright ? rng.uniform(185, 255) : rng.uniform(5, 70);
  const int sector = static_cast<int>(hue) % 6;
  const double f = hue - std::floor(hue);
  const double p = value * (1 - sat), q = value * (1 - sat * f), t = value * (1 - sat * (1 - f));
  double r = value, g = t, b = p;
  switch (sector) {
    case 0:
      r = value;
      g = t;
      b = p;
      break;
    case 1:
      r = q;
      g = value;
      b = p;
      break;
    case 2:
      r = p;
      g = value;
      b = t;
      break;
    case 3:
      r = p;
      g = q;
      b = value;
      break;
    case 4:
      r = t;
      g = p;
      b = value;
      break;
    default:
      r = value;
      g = p;
      b = q;
      break;
  }
  return cv::Scalar(b, g, r);
}

std::vector<cv::Point> rotated_rect(cv::Point2d c, double w, double h, double angle) {
  const double ca = std::cos(angle), sa = std::sin(angle);
  std::vector<cv::Point> pts;
  const double xs[4] = {-w / 2, w / 2, w / 2, -w / 2}, ys[4] = {-h / 2, -h / 2, h / 2, h / 2};
  for (int i = 0; i < 4; ++i)
    pts.emplace_back(cvRound(c.x + ca * xs[i] - sa * ys[i]), cvRound(c.y + sa * xs[i] + ca * ys[i]));
  return pts;
}

// Adds colour value noise with wavelength `wavelength_texels` and amplitude `amplitude`.
void add_noise_octave(cv::Mat& acc, double wavelength_texels, double amplitude, Rng& rng) {
  const int gw = std::max(2, static_cast<int>(std::ceil(acc.cols / wavelength_texels)) + 2);
  const int gh = std::max(2, static_cast<int>(std::ceil(acc.rows / wavelength_texels)) + 2);
  cv::Mat grid(gh, gw, CV_32FC3);
  for (int y = 0; y < gh; ++y)
    for (int x = 0; x < gw; ++x) {
      const double lum = rng.uniform(-1, 1);
      cv::Vec3f& v = grid.at<cv::Vec3f>(y, x);
      for (int c = 0; c < 3; ++c) v[c] = static_cast<float>(amplitude * (lum + 0.45 * rng.uniform(-1, 1)));
    }
  cv::Mat up;
  cv::resize(grid, up, acc.size(), 0, 0, cv::INTER_CUBIC);
  acc += up;
}

void draw_shape(cv::Mat& img, Rng& rng, double size_px) {
  const cv::Point2d c(rng.uniform(-0.1, 1.1) * img.cols, rng.uniform(-0.1, 1.1) * img.rows);
  const double s = size_px * rng.uniform(0.6, 1.4), angle = rng.uniform(0, 3.14159265);
  const cv::Scalar color = contrast_color(rng);
  const int thick = std::max(1, cvRound(s * rng.uniform(0.05, 0.15)));
  switch (rng.integer(0, 7)) {
    case 0: {  // rotated rectangle
      auto pts = rotated_rect(c, s, s * rng.uniform(0.3, 1.0), angle);
      cv::fillConvexPoly(img, pts, color, cv::LINE_AA);
      break;
    }
    case 1:  // ellipse, filled or outline
      cv::ellipse(img, c, cv::Size(cvRound(s / 2), cvRound(s * rng.uniform(0.2, 0.5))), angle * 57.3, 0, 360, color,
                  rng.chance(0.6) ? cv::FILLED : thick, cv::LINE_AA);
      break;
    case 2: {  // triangle
      std::vector<cv::Point> pts;
      for (int i = 0; i < 3; ++i) {
        const double a = angle + i * 2.094 + rng.uniform(-0.5, 0.5), r = s * rng.uniform(0.3, 0.6);
        pts.emplace_back(cvRound(c.x + r * std::cos(a)), cvRound(c.y + r * std::sin(a)));
      }
      cv::fillConvexPoly(img, pts, color, cv::LINE_AA);
      break;
    }
    case 3: {  // star-like polygon
      std::vector<cv::Point> pts;
      const int n = rng.integer(5, 9);
      for (int i = 0; i < n; ++i) {
        const double a = angle + i * 6.2832 / n, r = s * (i % 2 ? rng.uniform(0.15, 0.3) : rng.uniform(0.4, 0.6));
        pts.emplace_back(cvRound(c.x + r * std::cos(a)), cvRound(c.y + r * std::sin(a)));
      }
      cv::fillPoly(img, std::vector<std::vector<cv::Point>>{pts}, color, cv::LINE_AA);
      break;
    }
    case 4: {  // a finite patch of stripes with random widths (not periodic)
      const cv::Scalar other = contrast_color(rng);
      const int bars = rng.integer(3, 7);
      const double ca = std::cos(angle), sa = std::sin(angle);
      double x = -s / 2;
      for (int i = 0; i < bars && x < s / 2; ++i) {
        const double w = s / bars * rng.uniform(0.5, 1.5);
        const cv::Point2d bc(c.x + ca * (x + w / 2), c.y + sa * (x + w / 2));
        cv::fillConvexPoly(img, rotated_rect(bc, w, s * 0.8, angle), i % 2 ? color : other, cv::LINE_AA);
        x += w;
      }
      break;
    }
    case 5: {  // glyph-like stroke
      std::vector<cv::Point> pts;
      const int n = rng.integer(3, 6);
      for (int i = 0; i < n; ++i)
        pts.emplace_back(cvRound(c.x + s * rng.uniform(-0.5, 0.5)), cvRound(c.y + s * rng.uniform(-0.5, 0.5)));
      cv::polylines(img, pts, false, color, std::max(1, thick), cv::LINE_AA);
      break;
    }
    case 6: {  // characters
      static const char* kChars = "ABCDEFGHJKLMNPQRSTUVWXYZ0123456789#&%@";
      std::string text;
      const int n = rng.integer(1, 3);
      for (int i = 0; i < n; ++i) text += kChars[rng.integer(0, 36)];
      const int fonts[4] = {cv::FONT_HERSHEY_SIMPLEX, cv::FONT_HERSHEY_DUPLEX, cv::FONT_HERSHEY_COMPLEX,
                            cv::FONT_HERSHEY_TRIPLEX};
      const double scale = std::max(0.2, s / 25.0);
      cv::putText(img, text, cv::Point(cvRound(c.x - s / 2), cvRound(c.y + s / 3)), fonts[rng.integer(0, 3)], scale,
                  color, std::max(1, cvRound(scale * rng.uniform(1.0, 3.0))), cv::LINE_AA);
      break;
    }
    default: {  // ring with a contrasting core
      cv::circle(img, c, cvRound(s / 2), color, cv::FILLED, cv::LINE_AA);
      cv::circle(img, c, cvRound(s * rng.uniform(0.1, 0.35)), contrast_color(rng), cv::FILLED, cv::LINE_AA);
      break;
    }
  }
}

}  // namespace

cv::Mat make_albedo_texture(double size_u, double size_v, double texel_size, std::uint64_t seed) {
  Rng rng(seed);
  const int w = std::max(4, static_cast<int>(std::ceil(size_u / texel_size)));
  const int h = std::max(4, static_cast<int>(std::ceil(size_v / texel_size)));
  const cv::Scalar base = contrast_color(rng) * 0.5 + cv::Scalar(64, 64, 64);
  cv::Mat acc(h, w, CV_32FC3, base);
  // Multi-scale colour noise: wavelengths from a metre down to a few centimetres.
  const double wavelengths[4] = {1.0, 0.3, 0.09, 0.03}, amplitudes[4] = {60, 40, 28, 18};
  for (int i = 0; i < 4; ++i) add_noise_octave(acc, wavelengths[i] / texel_size, amplitudes[i], rng);
  cv::Mat img;
  acc.convertTo(img, CV_8UC3);
  // Shapes at several scales, larger ones first so small marks sit on top of them.
  const double area = size_u * size_v;
  const double sizes[5] = {0.5, 0.25, 0.12, 0.06, 0.03}, density[5] = {0.7, 2.5, 8.0, 20.0, 40.0};
  for (int k = 0; k < 5; ++k) {
    const double expected = area * density[k];
    int count = static_cast<int>(expected);
    if (rng.uniform() < expected - count) ++count;
    for (int i = 0; i < count; ++i) draw_shape(img, rng, sizes[k] / texel_size);
  }
  return img;
}

std::vector<cv::Mat> make_mip_chain(const cv::Mat& level0) {
  std::vector<cv::Mat> mip{level0};
  while (mip.back().cols >= 8 && mip.back().rows >= 8 && mip.size() < 8) {
    cv::Mat next;
    cv::resize(mip.back(), next, cv::Size(mip.back().cols / 2, mip.back().rows / 2), 0, 0, cv::INTER_AREA);
    mip.push_back(next);
  }
  return mip;
}

}  // namespace cslam::synth
