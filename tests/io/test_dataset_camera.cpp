// The camera a dataset folder runs with: named, camera.yaml, the TUM camera in the folder's name,
// else tum1 (flagged as a guess).
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "common/run_program.h"
#include "core/error.h"
#include "geometry/camera_io.h"
#include "io/dataset_camera.h"

using namespace cslam;

TEST(DatasetCamera, TumCameraFromTheFolderName) {
  EXPECT_EQ(tum_preset_from_name("/data/rgbd_dataset_freiburg2_xyz"), "tum2");
  EXPECT_EQ(tum_preset_from_name("/data/rgbd_dataset_freiburg3_long_office_household/"), "tum3");
  EXPECT_EQ(tum_preset_from_name("../shared/data/tum_fr1_desk"), "tum1");
  EXPECT_EQ(tum_preset_from_name("FR3-office.bag"), "tum3");
  EXPECT_EQ(tum_preset_from_name("/data/freiburg2/xyz"), "tum2");  // the parent names it
  EXPECT_EQ(tum_preset_from_name("/data/robot_1"), "");
  EXPECT_EQ(tum_preset_from_name("/data/frame_dump"), "");  // "fr" without a camera number
  EXPECT_EQ(tum_preset_from_name("/data/run_fr12"), "");    // fr12 is not fr1
  EXPECT_EQ(tum_preset_from_name("/data/afr1"), "");        // not a word of its own
  EXPECT_EQ(tum_preset_from_name("/data/freiburg4_x"), "");
  EXPECT_EQ(tum_preset_from_name(""), "");
}

TEST(DatasetCamera, NamedThenFileThenFolderNameThenDefault) {
  test::TempDir dir("cslam_dataset_camera");
  const std::string fr3 = dir / "rgbd_dataset_freiburg3_office";
  const std::string plain = dir / "robot_7";
  std::filesystem::create_directories(fr3);
  std::filesystem::create_directories(plain);

  DatasetCamera c = dataset_camera(fr3);
  EXPECT_EQ(c.camera.name, "tum3");
  EXPECT_FALSE(c.guessed);
  EXPECT_NE(c.source.find("folder name"), std::string::npos) << c.source;

  c = dataset_camera(plain);
  EXPECT_EQ(c.camera.name, "tum1");
  EXPECT_TRUE(c.guessed) << "a fall-back must say so";

  c = dataset_camera(fr3, "tum2");  // named: wins over the folder name
  EXPECT_EQ(c.camera.name, "tum2");
  EXPECT_FALSE(c.guessed);

  PinholeCamera own = camera_preset("synthetic");
  own.name = "rig";
  own.fx = 600;
  save_camera_file(own, fr3 + "/camera.yaml");  // the folder's own file wins over its name
  c = dataset_camera(fr3);
  EXPECT_EQ(c.camera.name, "rig");
  EXPECT_EQ(c.camera.fx, 600);
  EXPECT_FALSE(c.guessed);

  EXPECT_THROW(dataset_camera(plain, "tum9"), ConfigError);
}

TEST(DatasetCamera, Eth3dCalibrationTxt) {
  // ETH3D SLAM benchmark folders: TUM layout plus calibration.txt "fx fy cx cy", 739x458 images.
  test::TempDir dir("cslam_dataset_camera_eth3d");
  const std::string seq = dir / "table_3";
  std::filesystem::create_directories(seq + "/rgb");
  std::filesystem::create_directories(seq + "/depth");
  ASSERT_TRUE(cv::imwrite(seq + "/rgb/1.png", cv::Mat(458, 739, CV_8UC3, cv::Scalar(90, 90, 90))));
  ASSERT_TRUE(cv::imwrite(seq + "/depth/1.png", cv::Mat(458, 739, CV_16UC1, cv::Scalar(5000))));
  std::ofstream(seq + "/rgb.txt") << "# colour\n1.0 rgb/1.png\n";
  std::ofstream(seq + "/depth.txt") << "1.0 depth/1.png\n";
  std::ofstream(seq + "/calibration.txt") << "726.28 726.28 354.64 186.46\n";

  DatasetCamera c = dataset_camera(seq);
  EXPECT_EQ(c.camera.name, "calibration.txt");
  EXPECT_FALSE(c.guessed);
  EXPECT_DOUBLE_EQ(c.camera.fx, 726.28);
  EXPECT_DOUBLE_EQ(c.camera.cy, 186.46);
  EXPECT_EQ(c.camera.width, 739);
  EXPECT_EQ(c.camera.height, 458);
  EXPECT_FALSE(c.camera.has_distortion());
  EXPECT_EQ(c.camera.depth_factor, 5000.0);

  std::ofstream(seq + "/calibration.txt") << "726.28 726.28 354.64\n";  // not four numbers: ignored
  c = dataset_camera(seq);
  EXPECT_EQ(c.camera.name, "tum1");
  EXPECT_TRUE(c.guessed);
  std::ofstream(seq + "/calibration.txt") << "fx fy cx cy\n";
  EXPECT_TRUE(dataset_camera(seq).guessed);

  std::ofstream(seq + "/calibration.txt") << "726.28 726.28 354.64 186.46\n";
  PinholeCamera own = camera_preset("synthetic");
  own.name = "rig";
  save_camera_file(own, seq + "/camera.yaml");  // camera.yaml comes first
  EXPECT_EQ(dataset_camera(seq).camera.name, "rig");
}
