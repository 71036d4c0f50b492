#include "codec/codec_plugins.h"

#include <dlfcn.h>
#include <unistd.h>

#include <climits>
#include <stdexcept>

namespace cslam {

namespace {

// ../lib/cslam/ beside the running executable.
std::string plugin_dir() {
  char exe[PATH_MAX];
  const ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
  if (n <= 0) return "lib/cslam/";
  std::string path(exe, std::size_t(n));
  const std::size_t slash = path.rfind('/');
  return (slash == std::string::npos ? std::string(".") : path.substr(0, slash)) + "/../lib/cslam/";
}

// Maps the plugin (RTLD_NOW: a missing symbol fails here, not in the middle of a frame) and
// returns its table. Never unloaded.
const void* load_table(const char* file, const char* symbol) {
  const std::string path = plugin_dir() + file;
  void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!handle) throw std::runtime_error(std::string("cannot load the codec plugin ") + path + ": " + dlerror());
  using TableFn = const void* (*)();
  auto fn = reinterpret_cast<TableFn>(dlsym(handle, symbol));
  if (!fn) throw std::runtime_error("codec plugin " + path + " has no " + symbol);
  return fn();
}

}  // namespace

// Function-local statics: the loader is process-wide, and initialisation is thread-safe (a
// failed load throws and is tried again by the next call).
const ImageIoApi& image_io() {
  static const ImageIoApi& api =
      *static_cast<const ImageIoApi*>(load_table("libcslam_opencv_image_io.so", "cslam_image_io_api"));
  return api;
}

namespace video {
const H264Api& h264_engine() {
  static const H264Api& api = *static_cast<const H264Api*>(load_table("libcslam_h264.so", "cslam_h264_api"));
  return api;
}
}  // namespace video

}  // namespace cslam
