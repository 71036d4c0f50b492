#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "common/test_data.h"
#include "core/error.h"
#include "io/tum_dataset.h"

using namespace cslam;
namespace fs = std::filesystem;

namespace {
fs::path make_temp_dir(const std::string& name) {
  fs::path d = fs::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}
}  // namespace

TEST(Association, NearestUniqueWithinThreshold) {
  const std::vector<double> a{1.00, 1.033, 1.066, 1.10, 2.0};
  const std::vector<double> b{1.005, 1.030, 1.031, 1.075, 1.5};
  const auto pairs = associate_timestamps(a, b, 0.02);
  // 1.00-1.005, 1.033-1.031 (closer than 1.030), 1.066-1.075; 1.10 and 2.0 have no partner left.
  ASSERT_EQ(pairs.size(), 3u);
  EXPECT_EQ(pairs[0], std::make_pair(0, 0));
  EXPECT_EQ(pairs[1], std::make_pair(1, 2));
  EXPECT_EQ(pairs[2], std::make_pair(2, 3));
}

TEST(Association, NearestMayShareADepthImage) {
  const std::vector<double> a{1.00, 1.033, 1.066, 1.10, 2.0};
  const std::vector<double> b{1.005, 1.030, 1.031, 1.075, 1.5};
  const auto pairs = associate_nearest(a, b, 0.02);
  // 1.00-1.005, 1.033-1.031, 1.066-1.075, 1.10 has no depth within 0.02 s, 2.0 neither.
  ASSERT_EQ(pairs.size(), 3u);
  EXPECT_EQ(pairs[0], std::make_pair(0, 0));
  EXPECT_EQ(pairs[1], std::make_pair(1, 2));
  EXPECT_EQ(pairs[2], std::make_pair(2, 3));
  // A dropped depth frame: two colour frames share the one between them.
  const auto shared = associate_nearest({1.000, 1.033, 1.066}, {1.005, 1.050}, 0.02);
  ASSERT_EQ(shared.size(), 3u);
  EXPECT_EQ(shared[1], std::make_pair(1, 1));
  EXPECT_EQ(shared[2], std::make_pair(2, 1));
  EXPECT_EQ(associate_timestamps({1.000, 1.033, 1.066}, {1.005, 1.050}, 0.02).size(), 2u);
  EXPECT_EQ(parse_association("unique"), Association::kUnique);
  EXPECT_THROW(parse_association("closest"), ConfigError);
}

TEST(Range, OneBasedInclusive) {
  std::vector<RgbdPair> pairs(10);
  for (int i = 0; i < 10; ++i) pairs[i].index = i;
  const auto r = select_range(pairs, 3, 5);
  ASSERT_EQ(r.size(), 3u);
  EXPECT_EQ(r.front().index, 2);
  EXPECT_EQ(r.back().index, 4);
  EXPECT_THROW(select_range(pairs, 0, 5), std::out_of_range);
  EXPECT_THROW(select_range(pairs, 4, 11), std::out_of_range);
  EXPECT_EQ(parse_range("3:", 10), std::make_pair(3, 10));
  EXPECT_EQ(parse_range("2:7", 10), std::make_pair(2, 7));
  EXPECT_THROW(parse_range("2-7", 10), ConfigError);
}

TEST(TumDataset, ReadsSmallDatasetPngAndJpg) {
  const fs::path d = make_temp_dir("cslam_ds");
  fs::create_directories(d / "rgb");
  fs::create_directories(d / "depth");
  cv::Mat rgb(48, 64, CV_8UC3, cv::Scalar(10, 200, 30)), depth(48, 64, CV_16UC1, cv::Scalar(5000));
  cv::imwrite((d / "rgb/1.png").string(), rgb);
  cv::imwrite((d / "rgb/2.jpg").string(), rgb);
  cv::imwrite((d / "depth/1.png").string(), depth);
  cv::imwrite((d / "depth/2.png").string(), depth);
  std::ofstream(d / "rgb.txt") << "# rgb\n1.000 rgb/1.png\n1.033 rgb/2.jpg\n";
  std::ofstream(d / "depth.txt") << "# depth\n1.001 depth/1.png\n1.040 depth/2.png\n";
  std::ofstream(d / "groundtruth.txt") << "# gt\n1.0 0 0 0 0 0 0 1\n";
  const auto ds = open_tum_dataset(d.string());
  ASSERT_EQ(ds.pairs.size(), 2u);
  ASSERT_TRUE(ds.groundtruth.has_value());
  EXPECT_EQ(ds.groundtruth->size(), 1u);
  for (const auto& p : ds.pairs) {
    const auto im = load_rgbd(p);
    EXPECT_EQ(im.bgr.type(), CV_8UC3);
    EXPECT_EQ(cv::norm(im.bgr, cv::imread(p.rgb_path, cv::IMREAD_COLOR), cv::NORM_INF), 0.0) << p.rgb_path;
    EXPECT_EQ(im.depth.at<uint16_t>(0, 0), 5000);
  }
  fs::remove_all(d);
}

// A JPEG is recognised by its bytes, not its name; a damaged one is an InputError naming the file.
TEST(TumDataset, ColourImagesByContentAndDamagedJpegs) {
  const fs::path d = make_temp_dir("cslam_ds_jpeg");
  cv::Mat rgb(48, 64, CV_8UC3);
  cv::randu(rgb, 0, 256);
  std::vector<uchar> jpeg, png;
  cv::imencode(".jpg", rgb, jpeg);
  cv::imencode(".png", rgb, png);
  auto write = [&](const std::string& name, const std::vector<uchar>& bytes, std::size_t size) {
    std::ofstream(d / name, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(size));
    return (d / name).string();
  };
  const std::string jpeg_as_png = write("jpeg_named.png", jpeg, jpeg.size());
  const std::string png_as_jpg = write("png_named.jpg", png, png.size());
  EXPECT_EQ(cv::norm(load_colour_image(jpeg_as_png), cv::imdecode(jpeg, cv::IMREAD_COLOR), cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(load_colour_image(png_as_jpg), rgb, cv::NORM_INF), 0.0);
  for (const std::size_t keep : {std::size_t(0), std::size_t(2), std::size_t(30), jpeg.size() / 2, jpeg.size() - 2}) {
    const std::string path = write("cut_" + std::to_string(keep) + ".jpg", jpeg, keep);
    try {
      load_colour_image(path);
      ADD_FAILURE() << "accepted " << keep << " of " << jpeg.size() << " bytes";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(load_colour_image((d / "missing.jpg").string()), InputError);
  EXPECT_THROW(load_colour_image(d.string()), InputError);  // a folder
  fs::remove_all(d);
}

TEST(TumDataset, BadInputNamesFileAndLine) {
  const fs::path d = make_temp_dir("cslam_ds_bad");
  EXPECT_THROW(open_tum_dataset((d / "missing").string()), InputError);
  std::ofstream(d / "rgb.txt") << "# rgb\n1.000 rgb/1.png\nabc rgb/2.png\n";
  std::ofstream(d / "depth.txt") << "1.0 depth/1.png\n";
  try {
    open_tum_dataset(d.string());
    FAIL() << "malformed line accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("rgb.txt:3"), std::string::npos) << e.what();
  }
  std::ofstream(d / "rgb.txt") << "1.000 rgb/1.png\n";
  RgbdPair p = open_tum_dataset(d.string()).pairs.at(0);
  EXPECT_THROW(load_rgbd(p), InputError);  // image does not exist
  fs::remove_all(d);
}

TEST(TumDataset, RealSequence) {
  CSLAM_REQUIRE_TUM_RPY();
  const auto ds = open_tum_dataset(test::tum_rpy_dir());
  EXPECT_EQ(ds.rgb.size(), 723u);
  EXPECT_EQ(ds.depth.size(), 722u);
  // Every colour frame has a depth image within 0.02 s; 694 pairs one to one (the README).
  EXPECT_EQ(ds.pairs.size(), 723u);
  EXPECT_EQ(open_tum_dataset(test::tum_rpy_dir(), 0.02, Association::kUnique).pairs.size(), 694u);
  ASSERT_TRUE(ds.groundtruth.has_value());
  EXPECT_GT(ds.groundtruth->size(), 2000u);
  for (const auto& p : ds.pairs) EXPECT_LE(std::abs(p.rgb_time - p.depth_time), 0.02);
  const auto im = load_rgbd(ds.pairs.front());
  EXPECT_EQ(im.bgr.cols, 640);
  EXPECT_EQ(im.depth.rows, 480);
}

// load_rgbd decodes JPEGs with TurboJPEG; SLAM results stay unchanged only if every frame's pixels
// are exactly cv::imread's (about 2 s for the 723 frames).
TEST(TumDataset, RealSequenceColourIsBitIdenticalToImread) {
  CSLAM_REQUIRE_TUM_RPY();
  const auto ds = open_tum_dataset(test::tum_rpy_dir());
  int differing = 0;
  for (const auto& f : ds.rgb)
    if (cv::norm(load_colour_image(f.path), cv::imread(f.path, cv::IMREAD_COLOR), cv::NORM_INF) != 0) {
      ++differing;
      ADD_FAILURE() << f.path;
    }
  EXPECT_EQ(differing, 0);
}
