#pragma once
// Where the vocabulary tools get their images: TUM datasets (every n-th RGB frame), plain image
// folders (sorted *.png/*.jpg) and procedural images. Shared by cslam-vocab and the benchmarks.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace cslam {

struct ImageSource {
  std::string path;        // file path, or "procedural:<seed>"
  double timestamp = 0;    // TUM frames only
  std::uint64_t seed = 0;  // procedural only
};

// Every `every`-th RGB frame listed in <root>/rgb.txt. Throws InputError on a missing dataset.
std::vector<ImageSource> tum_images(const std::string& root, int every);
// Every `every`-th image (png/jpg/jpeg, sorted by name) of a folder. Throws InputError if missing.
std::vector<ImageSource> folder_images(const std::string& dir, int every);
// n procedural images with seeds first_seed, first_seed+1, ...
std::vector<ImageSource> procedural_images(int n, std::uint64_t first_seed);

// Loads one image as CV_8UC1; throws InputError naming the file if unreadable.
cv::Mat load_gray(const ImageSource& source);

// Runs fn(i) for i in [0,n) on `threads` threads.
void parallel_for_each(std::size_t n, int threads, const std::function<void(std::size_t)>& fn);

}  // namespace cslam
