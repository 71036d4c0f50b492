#include "image_sources.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <filesystem>
#include <mutex>
#include <thread>

#include <opencv2/imgcodecs.hpp>

#include "core/error.h"
#include "slam/features/procedural_image.h"
#include "io/tum_dataset.h"

namespace cslam {

std::vector<ImageSource> tum_images(const std::string& root, int every) {
  const TumDataset ds = open_tum_dataset(root);
  std::vector<ImageSource> out;
  for (std::size_t i = 0; i < ds.rgb.size(); i += std::size_t(std::max(1, every)))
    out.push_back({ds.rgb[i].path, ds.rgb[i].timestamp, 0});
  return out;
}

std::vector<ImageSource> folder_images(const std::string& dir, int every) {
  namespace fs = std::filesystem;
  if (!fs::is_directory(dir)) throw InputError(dir, "not a folder");
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(dir)) {
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    if (e.is_regular_file() && (ext == ".png" || ext == ".jpg" || ext == ".jpeg")) files.push_back(e.path().string());
  }
  std::sort(files.begin(), files.end());
  std::vector<ImageSource> out;
  for (std::size_t i = 0; i < files.size(); i += std::size_t(std::max(1, every))) out.push_back({files[i], 0, 0});
  return out;
}

std::vector<ImageSource> procedural_images(int n, std::uint64_t first_seed) {
  std::vector<ImageSource> out;
  for (int i = 0; i < n; ++i) out.push_back({"procedural:" + std::to_string(first_seed + i), 0, first_seed + i});
  return out;
}

cv::Mat load_gray(const ImageSource& source) {
  if (source.path.rfind("procedural:", 0) == 0) return procedural_image(source.seed);
  cv::Mat img = cv::imread(source.path, cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw InputError(source.path, "cannot read image");
  return img;
}

void parallel_for_each(std::size_t n, int threads, const std::function<void(std::size_t)>& fn) {
  if (threads <= 1) {
    for (std::size_t i = 0; i < n; ++i) fn(i);
    return;
  }
  std::atomic<std::size_t> next{0};
  std::mutex error_mutex;
  std::exception_ptr error;
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&] {
      for (std::size_t i = next++; i < n; i = next++) {
        try {
          fn(i);
        } catch (...) {
          std::lock_guard<std::mutex> lock(error_mutex);
          if (!error) error = std::current_exception();
          next = n;  // stop handing out work
        }
      }
    });
  for (std::thread& th : pool) th.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace cslam
