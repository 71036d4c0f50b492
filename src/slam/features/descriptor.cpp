#include "slam/features/descriptor.h"

#include <cstring>
#include <stdexcept>

namespace cslam {

int hamming_distance_naive(const Descriptor& a, const Descriptor& b) {
  int d = 0;
  for (int i = 0; i < 256; ++i) d += descriptor_bit(a, i) != descriptor_bit(b, i);
  return d;
}

Descriptor descriptor_from_row(const cv::Mat& row) {
  if (row.type() != CV_8UC1 || row.rows != 1 || row.cols != 32)
    throw std::invalid_argument("descriptor_from_row: expected a 1x32 CV_8U row");
  Descriptor d;
  std::memcpy(d.data(), row.ptr<std::uint8_t>(0), 32);
  return d;
}

cv::Mat descriptor_to_row(const Descriptor& d) {
  cv::Mat row(1, 32, CV_8UC1);
  std::memcpy(row.ptr<std::uint8_t>(0), d.data(), 32);
  return row;
}

std::vector<Descriptor> descriptors_from_mat(const cv::Mat& mat) {
  std::vector<Descriptor> out;
  if (mat.empty()) return out;
  if (mat.type() != CV_8UC1 || mat.cols != 32)
    throw std::invalid_argument("descriptors_from_mat: expected an N x 32 CV_8U matrix");
  out.resize(mat.rows);
  for (int r = 0; r < mat.rows; ++r) std::memcpy(out[r].data(), mat.ptr<std::uint8_t>(r), 32);
  return out;
}

}  // namespace cslam
