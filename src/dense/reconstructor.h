#pragma once
// Dense reconstruction from posed RGB-D frames: back-projection, per-chunk voxel filtering
// (bounded memory), optional outlier removal, optional TSDF fusion + marching-cubes mesh.
// Frames are given one by one; finish() returns the result.
#include <cstddef>
#include <memory>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "cloud/point_cloud.h"
#include "dense/dense_config.h"
#include "geometry/camera.h"
#include "geometry/se3.h"

namespace cslam {

enum class SkipReason { kNone, kNoImage, kBadPose, kBadImage, kWrongImageSize, kNoValidDepth };
const char* to_string(SkipReason reason);

struct IntegrateResult {
  bool used = false;
  SkipReason reason = SkipReason::kNone;  // why not used
  std::size_t points = 0;                 // points back-projected from this frame
};

struct DenseCounts {
  int used = 0;
  int no_image = 0;        // pose without an RGB-D pair within max_time_gap (counted by callers)
  int bad_pose = 0;        // NaN / infinite pose
  int bad_image = 0;       // empty, unreadable or wrong pixel type
  int wrong_size = 0;      // image size differs from the camera's
  int no_valid_depth = 0;  // no depth within [min_depth, max_depth] (e.g. all zero)
  int tsdf_frames = 0;     // frames fused into the TSDF
  int skipped() const { return no_image + bad_pose + bad_image + wrong_size + no_valid_depth; }
  void add(SkipReason reason);
};

struct DenseTiming {       // milliseconds
  double load = 0;         // image decoding (reconstruct_from_* only; on the loader thread)
  double backproject = 0;  // main thread
  double filter = 0;       // voxel filtering (filter thread when threads >= 2)
  double outliers = 0, tsdf = 0, mesh = 0, total = 0;
};

struct DenseResult {
  ColoredCloud cloud;  // voxel-filtered, coloured, in the poses' world frame
  TriangleMesh mesh;   // empty unless config.build_mesh
  DenseCounts counts;
  std::size_t raw_points = 0;            // points back-projected before filtering
  std::size_t peak_buffered_points = 0;  // most points held at once by the filter stage
  std::size_t tsdf_blocks = 0, tsdf_bytes = 0;
  DenseTiming timing;
};

class DenseReconstructor {
 public:
  explicit DenseReconstructor(DenseConfig config);  // throws ConfigError on a bad config
  ~DenseReconstructor();                            // joins the filter thread
  DenseReconstructor(const DenseReconstructor&) = delete;
  DenseReconstructor& operator=(const DenseReconstructor&) = delete;

  // Adds one frame (BGR CV_8UC3 and raw CV_16UC1 depth registered to it), the camera at
  // T_world_cam when the colour image was taken. If the depth image was taken elsewhere on the
  // camera's path (another instant), T_world_depthcam places it and colours are looked up where
  // its points project in the colour image. Bad frames are skipped and counted, never thrown.
  // Throws std::logic_error after finish().
  IntegrateResult integrate(const SE3& T_world_cam, const cv::Mat& bgr, const cv::Mat& depth16,
                            const PinholeCamera& camera, const std::optional<SE3>& T_world_depthcam = std::nullopt);
  // Records a frame skipped by the caller (e.g. a pose without image, an unreadable file).
  void count_skipped(SkipReason reason);
  void add_load_time(double ms);

  // Flushes, filters, removes outliers, meshes. Call once; the result may be empty (callers
  // decide; writers refuse empty clouds).
  DenseResult finish();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cslam
