#include "dense/backproject.h"

#include <algorithm>
#include <cstdint>

namespace cslam {

RayTable::RayTable(const PinholeCamera& camera) : camera_(camera) {
  camera_.validate();
  const int w = camera_.width, h = camera_.height;
  std::vector<Eigen::Vector2d> px;
  px.reserve(size_t(w) * size_t(h));
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) px.emplace_back(u, v);
  camera_.undistort_pixels(px);  // no-op without distortion
  rays_.resize(2 * px.size());
  for (size_t i = 0; i < px.size(); ++i) {
    const float x = float((px[i].x() - camera_.cx) / camera_.fx), y = float((px[i].y() - camera_.cy) / camera_.fy);
    rays_[2 * i] = x;
    rays_[2 * i + 1] = y;
    max_r2_ = std::max(max_r2_, x * x + y * y);
  }
}

PixelProjector::PixelProjector(const RayTable& rays) {
  const PinholeCamera& c = rays.camera();
  fx_ = float(c.fx), fy_ = float(c.fy), cx_ = float(c.cx), cy_ = float(c.cy);
  k1_ = float(c.dist[0]), k2_ = float(c.dist[1]), p1_ = float(c.dist[2]), p2_ = float(c.dist[3]),
  k3_ = float(c.dist[4]);
  max_r2_ = rays.max_radius2() * 1.0001f;
  distorted_ = c.has_distortion();
  width_ = c.width;
  height_ = c.height;
}

std::size_t backproject(const cv::Mat& bgr, const cv::Mat& depth, const RayTable& rays, const SE3& T_world_cam,
                        const BackprojectParams& params, ColoredCloud& out, const SE3* T_colourcam_depthcam) {
  const PinholeCamera& cam = rays.camera();
  const PixelProjector project(rays);
  const RigidF colour_from_depth(T_colourcam_depthcam);
  const Eigen::Matrix3f R = T_world_cam.R().cast<float>();
  const Eigen::Vector3f t = T_world_cam.translation().cast<float>();
  const float scale = float(cam.depth_scale_correction / cam.depth_factor);
  const float zmin = float(params.min_depth), zmax = float(params.max_depth);
  const int stride = std::max(1, params.stride);
  const size_t before = out.size();
  const size_t need = before + size_t(cam.width / stride + 1) * size_t(cam.height / stride + 1);
  if (out.points.capacity() < need) out.reserve(std::max(need, 2 * out.points.capacity()));  // amortised growth
  for (int v = 0; v < cam.height; v += stride) {
    const std::uint16_t* drow = depth.ptr<std::uint16_t>(v);
    const cv::Vec3b* crow = bgr.ptr<cv::Vec3b>(v);
    for (int u = 0; u < cam.width; u += stride) {
      const std::uint16_t raw = drow[u];
      if (raw == 0) continue;
      const float z = raw * scale;
      if (z < zmin || z > zmax) continue;
      const float* r = rays.ray(u, v);
      const Eigen::Vector3f p(r[0] * z, r[1] * z, z);
      out.points.push_back(R * p + t);
      int uc = u, vc = v;
      if (T_colourcam_depthcam && !project(colour_from_depth * p, uc, vc)) uc = u, vc = v;
      const cv::Vec3b& c = vc == v ? crow[uc] : bgr.at<cv::Vec3b>(vc, uc);
      out.colors.push_back({c[2], c[1], c[0]});
    }
  }
  return out.size() - before;
}

}  // namespace cslam
