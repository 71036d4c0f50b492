#include <random>

#include <gtest/gtest.h>

#include "slam/features/descriptor.h"

namespace cslam {
namespace {

Descriptor random_descriptor(std::mt19937_64& rng) { return {rng(), rng(), rng(), rng()}; }

TEST(Descriptor, HammingMatchesNaive) {
  std::mt19937_64 rng(7);
  for (int i = 0; i < 2000; ++i) {
    const Descriptor a = random_descriptor(rng), b = random_descriptor(rng);
    ASSERT_EQ(hamming_distance(a, b), hamming_distance_naive(a, b));
  }
  const Descriptor zero{0, 0, 0, 0}, ones{~0ull, ~0ull, ~0ull, ~0ull};
  EXPECT_EQ(hamming_distance(zero, ones), 256);
  EXPECT_EQ(hamming_distance(ones, ones), 0);
}

TEST(Descriptor, RowLayoutIsOpenCvBitOrder) {
  cv::Mat row = cv::Mat::zeros(1, 32, CV_8UC1);
  row.at<std::uint8_t>(0, 3) = 0x05;   // bits 24 and 26
  row.at<std::uint8_t>(0, 31) = 0x80;  // bit 255
  const Descriptor d = descriptor_from_row(row);
  for (int i = 0; i < 256; ++i) EXPECT_EQ(descriptor_bit(d, i), i == 24 || i == 26 || i == 255) << i;
  EXPECT_EQ(cv::norm(descriptor_to_row(d), row, cv::NORM_HAMMING), 0);
  // Hamming distance agrees with OpenCV's.
  std::mt19937_64 rng(3);
  const Descriptor a = random_descriptor(rng), b = random_descriptor(rng);
  EXPECT_EQ(hamming_distance(a, b), int(cv::norm(descriptor_to_row(a), descriptor_to_row(b), cv::NORM_HAMMING)));
}

TEST(Descriptor, RejectsWrongShape) {
  EXPECT_THROW(descriptor_from_row(cv::Mat::zeros(1, 31, CV_8UC1)), std::invalid_argument);
  EXPECT_THROW(descriptor_from_row(cv::Mat::zeros(1, 32, CV_32F)), std::invalid_argument);
  EXPECT_TRUE(descriptors_from_mat(cv::Mat()).empty());
  EXPECT_EQ(descriptors_from_mat(cv::Mat::zeros(5, 32, CV_8UC1)).size(), 5u);
}

}  // namespace
}  // namespace cslam
