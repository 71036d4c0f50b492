#include <cmath>
#include <set>
#include <thread>
#include <tuple>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/test_data.h"
#include "core/error.h"
#include "slam/features/matching.h"
#include "slam/features/orb_extractor.h"
#include "slam/features/opencv_threads.h"
#include "slam/features/procedural_image.h"
#include "io/tum_dataset.h"

namespace cslam {
namespace {

TEST(OrbExtractor, LevelBudgetsAndScales) {
  const OrbExtractor ex;
  ASSERT_EQ(ex.scale_factors().size(), 8u);
  EXPECT_DOUBLE_EQ(ex.scale_factors()[0], 1.0);
  EXPECT_NEAR(ex.scale_factors()[7], std::pow(1.2, 7), 1e-12);
  EXPECT_NEAR(ex.level_sigma2()[3] * ex.inv_level_sigma2()[3], 1.0, 1e-12);
  int sum = 0;
  for (int l = 0; l < 8; ++l) {
    sum += ex.features_per_level()[l];
    if (l > 0) {
      EXPECT_LE(ex.features_per_level()[l], ex.features_per_level()[l - 1]);
    }
  }
  EXPECT_EQ(sum, 1000);
  EXPECT_THROW(OrbExtractor(OrbConfig{0}), ConfigError);
  OrbConfig bad;
  bad.scale_factor = 1.0;
  EXPECT_THROW(OrbExtractor{bad}, ConfigError);
}

TEST(OrbExtractor, ThousandWellSpreadFeatures) {
  const cv::Mat img = procedural_image(5);
  const OrbExtractor ex;
  const OrbFeatures f = ex.extract(img);
  ASSERT_GE(f.size(), 950u);
  ASSERT_LE(f.size(), 1000u);
  ASSERT_EQ(f.descriptors.size(), f.size());
  ASSERT_EQ(f.undistorted.size(), f.size());
  std::vector<int> per_level(8, 0), per_cell(16, 0);
  for (std::size_t i = 0; i < f.size(); ++i) {
    const cv::KeyPoint& kp = f.keypoints[i];
    ASSERT_GE(kp.octave, 0);
    ASSERT_LT(kp.octave, 8);
    ++per_level[kp.octave];
    EXPECT_GE(kp.angle, 0.f);
    EXPECT_LT(kp.angle, 360.f);
    EXPECT_GE(kp.pt.x, 0.f);
    EXPECT_LT(kp.pt.x, 640.f);
    EXPECT_GE(kp.pt.y, 0.f);
    EXPECT_LT(kp.pt.y, 480.f);
    EXPECT_EQ(f.undistorted[i].x(), kp.pt.x);  // no camera -> unchanged
    ++per_cell[std::min(3, int(kp.pt.y / 120)) * 4 + std::min(3, int(kp.pt.x / 160))];
  }
  for (int l = 0; l < 8; ++l) EXPECT_GT(per_level[l], 0) << "level " << l;
  EXPECT_GT(per_level[0], per_level[7]);
  // Evenly distributed: every cell of a 4x4 grid holds a fair share.
  for (int c = 0; c < 16; ++c) EXPECT_GT(per_cell[c], 20) << "cell " << c;
}

TEST(OrbExtractor, EveryLevelMapsToLevelZeroWithPixelCentresAligned) {
  // A keypoint of a coarse level must land where its structure is in the full image. Mirroring
  // the image mirrors every level (cv::resize aligns pixel centres), so a corner found at level l
  // in both images must map to x0 and W - 1 - x0 in level-0 pixels. Scaling level pixels by the
  // nominal factor instead (x * 1.2^l) puts them up to 1.2 px off at level 7 of a 640-pixel image,
  // and breaks this symmetry at every level above 0 (measured: none of a level's keypoints then
  // mirror; 85-94 % do with the mapping right, the rest differ in FAST's or the quadtree's ties).
  const cv::Mat img = procedural_image(23);
  cv::Mat mirrored;
  cv::flip(img, mirrored, 1);
  const OrbExtractor ex;
  const OrbFeatures a = ex.extract(img), b = ex.extract(mirrored);
  std::set<std::tuple<int, float, float>> in_b;
  for (const auto& kp : b.keypoints) in_b.insert({kp.octave, kp.pt.x, kp.pt.y});
  std::vector<int> total(8, 0), mirrored_found(8, 0);
  for (const auto& kp : a.keypoints) {
    ++total[kp.octave];
    const float x = float(img.cols - 1) - kp.pt.x;
    auto it = in_b.lower_bound({kp.octave, x - 1e-3f, kp.pt.y - 1e-3f});
    for (; it != in_b.end() && std::get<0>(*it) == kp.octave && std::get<1>(*it) <= x + 1e-3f; ++it)
      if (std::abs(std::get<2>(*it) - kp.pt.y) < 1e-3f) {
        ++mirrored_found[kp.octave];
        break;
      }
  }
  for (int l = 0; l < 8; ++l) {
    ASSERT_GT(total[l], 5) << "level " << l;
    EXPECT_GT(mirrored_found[l], 0.5 * total[l]) << "level " << l << ": " << mirrored_found[l] << " of " << total[l];
  }
}

TEST(OrbExtractor, StrongCornersAreLocatedInsideTheirPixel) {
  // The same texture seen half a pixel apart (shifted by -0.25 and +0.25 px, so both images are
  // blurred alike by the interpolation): a corner on whole pixels is off by half a pixel in one of
  // the two, whichever way it rounds. Placed at the peak of its FAST scores it follows the shift.
  const cv::Mat img = procedural_image(29);
  auto shifted = [&](double dx) {
    cv::Mat out;
    const cv::Mat m = (cv::Mat_<double>(2, 3) << 1, 0, dx, 0, 1, 0);
    cv::warpAffine(img, out, m, img.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
    return out;
  };
  const cv::Mat a = shifted(-0.25), b = shifted(0.25);
  auto shift_error_rms = [&](bool subpixel) {
    OrbConfig c;
    c.subpixel = subpixel;
    const OrbExtractor ex(c);
    const OrbFeatures fa = ex.extract(a), fb = ex.extract(b);
    double sum = 0;
    int n = 0;
    for (const auto& ka : fa.keypoints) {
      if (ka.octave != 0 || ka.response < c.ini_fast_threshold) continue;
      for (const auto& kb : fb.keypoints)
        if (kb.octave == 0 && std::abs(kb.pt.y - ka.pt.y) < 0.6f && std::abs(kb.pt.x - ka.pt.x - 0.5f) < 0.9f) {
          const double e = kb.pt.x - ka.pt.x - 0.5;
          sum += e * e;
          ++n;
          break;
        }
    }
    EXPECT_GT(n, 50);
    return std::sqrt(sum / std::max(1, n));
  };
  const double whole = shift_error_rms(false), inside = shift_error_rms(true);
  std::printf("half-pixel shift, RMS error of strong level-0 corners: %.3f px on whole pixels, %.3f px inside\n", whole,
              inside);
  EXPECT_GT(whole, 0.4);
  EXPECT_LT(inside, 0.6 * whole);
}

TEST(OrbExtractor, EmptyBlackAndTinyImagesGiveNoFeatures) {
  const OrbExtractor ex;
  EXPECT_EQ(ex.extract(cv::Mat()).size(), 0u);
  EXPECT_EQ(ex.extract(cv::Mat::zeros(480, 640, CV_8UC1)).size(), 0u);
  EXPECT_EQ(ex.extract(cv::Mat(12, 9, CV_8UC1, cv::Scalar(100))).size(), 0u);
  EXPECT_THROW(ex.extract(cv::Mat::zeros(10, 10, CV_32F)), std::invalid_argument);
  // Colour input is accepted.
  cv::Mat bgr;
  cv::cvtColor(procedural_image(9), bgr, cv::COLOR_GRAY2BGR);
  EXPECT_GT(ex.extract(bgr).size(), 900u);
}

TEST(OrbExtractor, DescriptorsAreRotationInvariant) {
  // The same scene rotated by 90 degrees: descriptors must still match, with a consistent
  // keypoint-angle difference of about 90 degrees.
  const cv::Mat img = procedural_image(11);
  cv::Mat rotated;
  cv::rotate(img, rotated, cv::ROTATE_90_CLOCKWISE);
  const OrbExtractor ex;
  const OrbFeatures a = ex.extract(img), b = ex.extract(rotated);
  MatchParams p;
  p.check_orientation = false;
  const std::vector<Match> matches = match_brute_force(a, b, p);
  ASSERT_GT(matches.size(), 150u);
  int geometric = 0, angle_ok = 0;
  for (const Match& m : matches) {
    const cv::Point2f pa = a.keypoints[m.a].pt, pb = b.keypoints[m.b].pt;
    // ROTATE_90_CLOCKWISE: (x, y) -> (H - 1 - y, x)
    if (std::hypot(pb.x - (img.rows - 1 - pa.y), pb.y - pa.x) < 3.0 * (1 << 1)) ++geometric;
    double d = std::fmod(b.keypoints[m.b].angle - a.keypoints[m.a].angle + 720.0, 360.0);
    if (std::abs(d - 90.0) < 15.0) ++angle_ok;
  }
  EXPECT_GT(geometric, 0.8 * matches.size());
  EXPECT_GT(angle_ok, 0.8 * matches.size());
}

TEST(OrbExtractor, Level0DescriptorsEqualOpenCvOrbWithOurAngles) {
  // Level-0 keypoints: OpenCV's ORB on the same image, keypoints and angles gives the same bits,
  // byte j bit i -> descriptor bit 8j+i.
  const cv::Mat img = procedural_image(13);
  const OrbExtractor ex;
  const OrbFeatures f = ex.extract(img);
  std::vector<cv::KeyPoint> kps;
  std::vector<int> index;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (f.keypoints[i].octave != 0) continue;
    cv::KeyPoint kp = f.keypoints[i];
    kp.class_id = int(i);
    kps.push_back(kp);
  }
  ASSERT_GT(kps.size(), 100u);
  cv::Ptr<cv::ORB> orb = cv::ORB::create(1000, 1.2f, 1, 19, 0, 2, cv::ORB::FAST_SCORE, 31, 20);
  cv::Mat desc;
  orb->compute(img, kps, desc);
  ASSERT_EQ(desc.rows, int(kps.size()));
  for (int r = 0; r < desc.rows; ++r) {
    const Descriptor& ours = f.descriptors[kps[r].class_id];
    ASSERT_EQ(ours, descriptor_from_row(desc.row(r))) << "keypoint " << kps[r].class_id;
  }
}

TEST(OrbExtractor, FastScoreSelectionEqualsDetectionAtTheInitialThreshold) {
  // The extractor runs FAST once at the fallback threshold and keeps corners scoring >= the
  // initial threshold in textured cells: that must be exactly FAST at the initial threshold.
  const cv::Mat img = procedural_image(17);
  std::vector<cv::KeyPoint> at20, at7;
  cv::FAST(img, at20, 20, true);
  cv::FAST(img, at7, 7, true);
  std::set<std::pair<float, float>> expected, selected;
  for (const auto& k : at20) expected.insert({k.pt.x, k.pt.y});
  for (const auto& k : at7)
    if (k.response >= 20.f) selected.insert({k.pt.x, k.pt.y});
  ASSERT_GT(expected.size(), 500u);
  EXPECT_EQ(selected, expected);
}

TEST(OrbExtractor, LevelCornersFollowTheCellRuleOfTwoFastPasses) {
  // ORB-SLAM2's rule written out with cv::FAST: per cell of the area inside the border, the
  // corners of a pass at the initial threshold if the cell has any, else those of a pass at the
  // fallback threshold. One level and a budget above the corner count, so the quadtree keeps all.
  cv::Mat img = procedural_image(17);
  // The left third at a fifth of its contrast: cells there have no strong corner.
  cv::Mat left = img.colRange(0, img.cols / 3);
  left.convertTo(left, CV_8U, 0.2, 0.8 * 128);
  OrbConfig c;
  c.num_levels = 1;
  c.num_features = 1000000;
  c.subpixel = false;
  const OrbFeatures f = OrbExtractor(c).extract(img);

  const int b = c.edge_threshold, W = img.cols, H = img.rows;
  const cv::Rect region(b - 3, b - 3, W - 2 * b + 6, H - 2 * b + 6);
  const int inner_w = W - 2 * b, inner_h = H - 2 * b;
  const int cols = inner_w / c.cell_size, rows = inner_h / c.cell_size;
  const float cell_w = float(inner_w) / cols, cell_h = float(inner_h) / rows;
  auto cell_of = [&](const cv::Point2f& p) {
    if (p.x < b || p.y < b || p.x >= W - b || p.y >= H - b) return -1;
    return std::min(rows - 1, int((p.y - b) / cell_h)) * cols + std::min(cols - 1, int((p.x - b) / cell_w));
  };
  std::vector<cv::KeyPoint> strong, weak;
  cv::FAST(img(region), strong, c.ini_fast_threshold, true);
  cv::FAST(img(region), weak, c.min_fast_threshold, true);
  std::vector<char> has_strong(std::size_t(cols * rows), 0);
  std::set<std::pair<float, float>> expected;
  for (const auto& k : strong) {
    const cv::Point2f p = k.pt + cv::Point2f(float(region.x), float(region.y));
    if (const int cell = cell_of(p); cell >= 0) {
      has_strong[std::size_t(cell)] = 1;
      expected.insert({p.x, p.y});
    }
  }
  int weak_cells = 0, weak_corners = 0;
  for (char h : has_strong) weak_cells += h ? 0 : 1;
  for (const auto& k : weak) {
    const cv::Point2f p = k.pt + cv::Point2f(float(region.x), float(region.y));
    if (const int cell = cell_of(p); cell >= 0 && !has_strong[std::size_t(cell)]) {
      expected.insert({p.x, p.y});
      ++weak_corners;
    }
  }
  ASSERT_GT(weak_cells, 20);
  ASSERT_GT(weak_corners, 100);
  ASSERT_GT(expected.size(), 1000u);
  std::set<std::pair<float, float>> got;
  for (const auto& k : f.keypoints) got.insert({k.pt.x, k.pt.y});
  EXPECT_EQ(got.size(), f.keypoints.size());
  EXPECT_EQ(got, expected);
}

TEST(OrbExtractor, ThreadSafeConstExtraction) {
  const OrbExtractor ex;
  const cv::Mat img = procedural_image(21);
  const OrbFeatures ref = ex.extract(img);
  std::vector<OrbFeatures> out(4);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) threads.emplace_back([&, t] { out[t] = ex.extract(img); });
  for (auto& th : threads) th.join();
  for (const OrbFeatures& f : out) {
    ASSERT_EQ(f.size(), ref.size());
    for (std::size_t i = 0; i < f.size(); ++i) ASSERT_EQ(f.descriptors[i], ref.descriptors[i]);
  }
}

TEST(OrbExtractor, RealFrameWithDistortion) {
  CSLAM_REQUIRE_TUM_RPY();
  const TumDataset ds = open_tum_dataset(test::tum_rpy_dir());
  const cv::Mat img = cv::imread(ds.rgb[100].path, cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(img.empty());
  const PinholeCamera cam = camera_tum_fr1();
  const OrbExtractor ex;
  const OrbFeatures f = ex.extract(img, &cam);
  EXPECT_GE(f.size(), 950u);
  for (std::size_t i = 0; i < f.size(); i += 37) {
    const Eigen::Vector2d u = cam.undistort_pixel({f.keypoints[i].pt.x, f.keypoints[i].pt.y});
    EXPECT_NEAR((u - f.undistorted[i]).norm(), 0.0, 1e-6);
  }
  // Strong radial distortion: some corner features move by several pixels.
  double max_shift = 0;
  for (std::size_t i = 0; i < f.size(); ++i)
    max_shift =
        std::max(max_shift, (f.undistorted[i] - Eigen::Vector2d(f.keypoints[i].pt.x, f.keypoints[i].pt.y)).norm());
  EXPECT_GT(max_shift, 3.0);
}

TEST(Quadtree, KeepsStrongestAndSpreads) {
  std::vector<cv::KeyPoint> kps;
  // A dense cluster in one corner plus a few isolated points elsewhere.
  for (int i = 0; i < 200; ++i) kps.emplace_back(cv::Point2f(10.f + (i % 20), 10.f + (i / 20)), 7.f, -1.f, float(i));
  kps.emplace_back(cv::Point2f(500, 400), 7.f, -1.f, 1.f);
  kps.emplace_back(cv::Point2f(300, 50), 7.f, -1.f, 1.f);
  const auto out = distribute_quadtree(kps, cv::Rect2f(0, 0, 640, 480), 10);
  ASSERT_GE(out.size(), 3u);
  ASSERT_LE(out.size(), 10u);
  bool far1 = false, far2 = false, best = false;
  for (const auto& k : out) {
    far1 |= k.pt.x == 500.f;
    far2 |= k.pt.x == 300.f;
    best |= k.response == 199.f;
  }
  EXPECT_TRUE(far1 && far2) << "isolated keypoints must survive";
  EXPECT_TRUE(best) << "the strongest keypoint of the cluster must survive";
  EXPECT_EQ(distribute_quadtree(kps, cv::Rect2f(0, 0, 640, 480), 1000).size(), kps.size());
  EXPECT_TRUE(distribute_quadtree({}, cv::Rect2f(0, 0, 640, 480), 10).empty());
}

}  // namespace
}  // namespace cslam

TEST(OpenCvThreads, ProgramsRunOpenCvOnTheCallingThread) {
  cv::setNumThreads(-1);  // OpenCV's default pool
  cslam::run_opencv_on_calling_threads();
  EXPECT_EQ(cv::getNumThreads(), 1);
}
