#include "support/synth/renderer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>
#include <vector>

#include "core/error.h"
#include "support/synth/random.h"
#include "support/synth/trajectory_planner.h"

namespace cslam::synth {
namespace {

// Per-face constants for one camera pose. With r = ((u - cx)/fx, (v - cy)/fy, 1) the ray of pixel
// (u, v) in the camera frame, a face point seen at camera depth z satisfies
//   den(u, v) = n_cam . r,  z = D / den,  s = s0 + z * S(u, v),  t = t0 + z * T(u, v),
// where den, S and T are affine in (u, v).
struct FaceSetup {
  int face = -1;
  int u0 = 0, u1 = -1, v0 = 0, v1 = -1;  // inclusive pixel bounding box
  float den_u = 0, den_v = 0, den_c = 0;
  float su = 0, sv = 0, sc = 0, s0 = 0;
  float tu = 0, tv = 0, tc = 0, t0 = 0;
  float D = 0;
  float size_u = 0, size_v = 0;
  bool disc = false;
  int texture = 0;
  float tex_u0 = 0, tex_v0 = 0;  // texture offsets in texels
  // Projected polygon (face clipped at the near plane), for the per-row pixel span.
  int nvert = 0;
  float pu[8] = {}, pv[8] = {};

  // Pixel columns [first, last] the face may cover on row v (a 1-pixel safety margin; the exact
  // coverage test on (s, t) decides).
  void span(float v, int& first, int& last) const {
    float lo = 1e30f, hi = -1e30f;
    for (int k = 0; k < nvert; ++k) {
      const int k2 = (k + 1) % nvert;
      const float va = pv[k], vb = pv[k2];
      if ((va <= v && vb >= v) || (vb <= v && va >= v)) {
        float x;
        if (std::abs(vb - va) < 1e-6f) {
          lo = std::min({lo, pu[k], pu[k2]});
          hi = std::max({hi, pu[k], pu[k2]});
          continue;
        }
        x = pu[k] + (v - va) / (vb - va) * (pu[k2] - pu[k]);
        lo = std::min(lo, x);
        hi = std::max(hi, x);
      }
    }
    first = std::max(u0, static_cast<int>(std::floor(lo)) - 1);
    last = std::min(u1, static_cast<int>(std::ceil(hi)) + 1);
  }
};

std::vector<FaceSetup> setup_faces(const Scene& scene, const PinholeCamera& cam, const SE3& T_world_cam, double near) {
  std::vector<FaceSetup> out;
  const Eigen::Matrix3d R = T_world_cam.R();
  const Eigen::Vector3d C = T_world_cam.translation();
  const double ifx = 1.0 / cam.fx, ify = 1.0 / cam.fy;
  auto affine = [&](const Eigen::Vector3d& w, float& a_u, float& a_v, float& a_c) {
    const Eigen::Vector3d c = R.transpose() * w;  // a . (R r) = (R^T a) . r
    a_u = static_cast<float>(c.x() * ifx);
    a_v = static_cast<float>(c.y() * ify);
    a_c = static_cast<float>(c.z() - c.x() * cam.cx * ifx - c.y() * cam.cy * ify);
  };
  for (size_t i = 0; i < scene.faces.size(); ++i) {
    const Face& f = scene.faces[i];
    const double D = f.normal.dot(f.origin - C);
    if (D >= -1e-9) continue;  // camera behind or on the face's plane
    // Corners in the camera frame, clipped against z >= near (Sutherland-Hodgman).
    const Eigen::Vector3d corners_w[4] = {f.origin, f.point(f.size_u, 0), f.point(f.size_u, f.size_v),
                                          f.point(0, f.size_v)};
    Eigen::Vector3d corners[4];
    for (int k = 0; k < 4; ++k) corners[k] = R.transpose() * (corners_w[k] - C);
    std::vector<Eigen::Vector3d> poly;
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector3d &a = corners[k], &b = corners[(k + 1) % 4];
      const bool ina = a.z() >= near, inb = b.z() >= near;
      if (ina) poly.push_back(a);
      if (ina != inb) poly.push_back(a + (b - a) * ((near - a.z()) / (b.z() - a.z())));
    }
    if (poly.empty()) continue;
    double umin = 1e30, umax = -1e30, vmin = 1e30, vmax = -1e30;
    FaceSetup s;
    for (const auto& p : poly) {
      const double u = cam.fx * p.x() / p.z() + cam.cx, v = cam.fy * p.y() / p.z() + cam.cy;
      umin = std::min(umin, u);
      umax = std::max(umax, u);
      vmin = std::min(vmin, v);
      vmax = std::max(vmax, v);
      // Clamp far-out vertices (nearly at the near plane) to keep float precision; spans are
      // clamped to the image anyway.
      s.pu[s.nvert] = static_cast<float>(std::clamp(u, -1e6, 1e6));
      s.pv[s.nvert] = static_cast<float>(std::clamp(v, -1e6, 1e6));
      ++s.nvert;
    }
    s.face = static_cast<int>(i);
    s.u0 = static_cast<int>(std::max(0.0, std::floor(umin)));
    s.u1 = static_cast<int>(std::min(cam.width - 1.0, std::ceil(umax)));
    s.v0 = static_cast<int>(std::max(0.0, std::floor(vmin)));
    s.v1 = static_cast<int>(std::min(cam.height - 1.0, std::ceil(vmax)));
    if (s.u0 > s.u1 || s.v0 > s.v1) continue;
    affine(f.normal, s.den_u, s.den_v, s.den_c);
    affine(f.axis_u, s.su, s.sv, s.sc);
    affine(f.axis_v, s.tu, s.tv, s.tc);
    s.s0 = static_cast<float>(f.axis_u.dot(C - f.origin));
    s.t0 = static_cast<float>(f.axis_v.dot(C - f.origin));
    s.D = static_cast<float>(D);
    s.size_u = static_cast<float>(f.size_u);
    s.size_v = static_cast<float>(f.size_v);
    s.disc = f.disc;
    s.texture = f.texture;
    s.tex_u0 = static_cast<float>(f.tex_u0 / scene.config.texel_size);
    s.tex_v0 = static_cast<float>(f.tex_v0 / scene.config.texel_size);
    out.push_back(s);
  }
  return out;
}

// One mip level of a texture, with its scale relative to level 0 (odd sizes round down).
struct TexLevel {
  const cv::Mat* image = nullptr;
  float sx = 1, sy = 1;
};

std::vector<std::vector<TexLevel>> texture_levels(const Scene& scene) {
  std::vector<std::vector<TexLevel>> out;
  for (const auto& t : scene.textures) {
    out.emplace_back();
    for (const auto& m : t.mip)
      out.back().push_back(
          {&m, static_cast<float>(m.cols) / t.mip[0].cols, static_cast<float>(m.rows) / t.mip[0].rows});
  }
  return out;
}

// Approximately standard normal from 4 uniform 16-bit chunks of a 64-bit hash (Irwin-Hall).
inline float approx_gauss(std::uint64_t h) {
  const float sum = static_cast<float>((h & 0xFFFF) + ((h >> 16) & 0xFFFF) + ((h >> 32) & 0xFFFF) + (h >> 48));
  return (sum * (1.0f / 65536.0f) - 2.0f) * 1.7320508f;  // variance of the sum is 4/12
}

}  // namespace

struct Renderer::Pass {
  const Renderer& r;
  std::vector<FaceSetup> faces;
  std::vector<std::vector<TexLevel>> textures;
  std::uint64_t seed;
  bool depth_noise, image_noise;
  cv::Mat& bgr;
  cv::Mat* depth;

  void run_rows(int row0, int row1) const {
    const PinholeCamera& cam = r.camera_;
    const int w = cam.width;
    const int n = (row1 - row0) * w;
    std::vector<float> zbuf(n, std::numeric_limits<float>::infinity()), sbuf(n), tbuf(n);
    std::vector<int> fbuf(n, -1);
    const float near = static_cast<float>(r.options_.near_clip);
    // 1. Rasterise every face into the band (z-buffer).
    for (int fi = 0; fi < static_cast<int>(faces.size()); ++fi) {
      const FaceSetup& f = faces[fi];
      const int va = std::max(f.v0, row0), vb = std::min(f.v1, row1 - 1);
      const float r2 = 0.25f * f.size_u * f.size_u, hu = 0.5f * f.size_u, hv = 0.5f * f.size_v;
      for (int v = va; v <= vb; ++v) {
        const float fv = static_cast<float>(v);
        const float drow = f.den_v * fv + f.den_c, srow = f.sv * fv + f.sc, trow = f.tv * fv + f.tc;
        const int base = (v - row0) * w;
        float* zr = zbuf.data() + base;
        int ua = 0, ub = -1;
        f.span(fv, ua, ub);
        for (int u = ua; u <= ub; ++u) {
          const float fu = static_cast<float>(u);
          const float den = f.den_u * fu + drow;
          if (den >= -1e-7f) continue;
          const float z = f.D / den;
          if (z >= zr[u] || z < near) continue;
          const float s = f.s0 + z * (f.su * fu + srow), t = f.t0 + z * (f.tu * fu + trow);
          if (s < 0 || t < 0 || s > f.size_u || t > f.size_v) continue;
          if (f.disc && (s - hu) * (s - hu) + (t - hv) * (t - hv) > r2) continue;
          zr[u] = z;
          sbuf[base + u] = s;
          tbuf[base + u] = t;
          fbuf[base + u] = fi;
        }
      }
    }
    // 2. Shade: texture lookup at the mip level matching the pixel footprint; depth.
    const Scene& scene = r.scene_;
    const float texel = static_cast<float>(scene.config.texel_size);
    const float ifx = static_cast<float>(1.0 / cam.fx), ify = static_cast<float>(1.0 / cam.fy);
    const float cx = static_cast<float>(cam.cx), cy = static_cast<float>(cam.cy);
    const float inv_texel = 1.0f / texel, inv_fx_texel = static_cast<float>(1.0 / (cam.fx * scene.config.texel_size));
    const Degradation& deg = r.options_.degradation;
    const float cos_grazing = static_cast<float>(std::cos(deg.grazing_angle_deg * 3.14159265358979 / 180.0));
    const float min_d = static_cast<float>(r.options_.min_depth), max_d = static_cast<float>(r.options_.max_depth);
    const float dfac = static_cast<float>(cam.depth_factor);
    for (int v = row0; v < row1; ++v) {
      cv::Vec3b* out = bgr.ptr<cv::Vec3b>(v);
      std::uint16_t* dout = depth ? depth->ptr<std::uint16_t>(v) : nullptr;
      const float yn = (v - cy) * ify;
      for (int u = 0; u < w; ++u) {
        const int idx = (v - row0) * w + u;
        const int fi = fbuf[idx];
        std::uint64_t h = 0;
        if (depth_noise || image_noise) h = mix64(seed ^ (static_cast<std::uint64_t>(v) * 0x9E3779B97F4A7C15ull + u));
        if (fi < 0) {
          out[u] = cv::Vec3b(0, 0, 0);
          if (dout) dout[u] = 0;
          continue;
        }
        const FaceSetup& f = faces[fi];
        const auto& levels = textures[f.texture];
        const float z = zbuf[idx];
        const float xn = (u - cx) * ifx;
        const float rr = xn * xn + yn * yn + 1.0f;
        const float aden = -(f.den_u * u + f.den_v * v + f.den_c);  // |n . r| = cos(angle) |r| > 0
        // Footprint of the pixel on the surface in texels, z |r|^2 / (fx |n . r|) (anisotropy capped).
        const float footprint = z * rr * inv_fx_texel / std::max(aden, 0.25f);
        int level = footprint >= 2.0f ? std::ilogb(footprint) : 0;
        level = std::min(level, static_cast<int>(levels.size()) - 1);
        const TexLevel& lv = levels[level];
        const cv::Mat& tex = *lv.image;
        float tx = (sbuf[idx] * inv_texel + f.tex_u0) * lv.sx - 0.5f;
        float ty = (tbuf[idx] * inv_texel + f.tex_v0) * lv.sy - 0.5f;
        tx = std::clamp(tx, 0.0f, tex.cols - 1.001f);
        ty = std::clamp(ty, 0.0f, tex.rows - 1.001f);
        const int x0 = static_cast<int>(tx), y0 = static_cast<int>(ty);
        const float ax = tx - x0, ay = ty - y0;
        const cv::Vec3b* p0 = tex.ptr<cv::Vec3b>(y0) + x0;
        const cv::Vec3b* p1 = tex.ptr<cv::Vec3b>(std::min(y0 + 1, tex.rows - 1)) + x0;
        const int dx = x0 + 1 < tex.cols ? 1 : 0;
        cv::Vec3b c;
        for (int k = 0; k < 3; ++k) {
          const float top = p0[0][k] + ax * (p0[dx][k] - p0[0][k]);
          const float bot = p1[0][k] + ax * (p1[dx][k] - p1[0][k]);
          float val = top + ay * (bot - top);
          if (image_noise) val += static_cast<float>(deg.image_noise_sigma) * approx_gauss(mix64(h + 1 + k));
          c[k] = cv::saturate_cast<uchar>(val);
        }
        out[u] = c;
        if (!dout) continue;
        float zd = z;
        if (depth_noise) {
          if (aden < cos_grazing * std::sqrt(rr))
            zd = 0;  // cos(angle) below the limit
          else
            zd += static_cast<float>(deg.depth_noise_coeff) * z * z * approx_gauss(h);
        }
        dout[u] =
            (zd >= min_d && zd <= max_d) ? static_cast<std::uint16_t>(std::min(65535.0f, std::round(zd * dfac))) : 0;
      }
    }
  }
};

Renderer::Renderer(const Scene& scene, const PinholeCamera& camera, RenderOptions options)
    : scene_(scene), camera_(camera), options_(options) {
  camera_.validate();
  if (camera_.has_distortion())
    throw ConfigError("synth renderer: camera '" + camera_.name +
                      "' has distortion; only undistorted pinhole cameras are supported");
  if (!(options_.near_clip > 0) || !(options_.max_depth > options_.min_depth) || options_.threads < 1)
    throw ConfigError("synth renderer: need near_clip > 0, max_depth > min_depth, threads >= 1");
}

void Renderer::render_pass(const SE3& T_world_cam, std::uint64_t noise_seed, bool depth_noise, bool image_noise,
                           cv::Mat& bgr, cv::Mat* depth) const {
  bgr.create(camera_.height, camera_.width, CV_8UC3);
  if (depth) depth->create(camera_.height, camera_.width, CV_16UC1);
  Pass pass{*this,
            setup_faces(scene_, camera_, T_world_cam, options_.near_clip),
            texture_levels(scene_),
            noise_seed,
            depth_noise,
            image_noise,
            bgr,
            depth};
  const int threads = std::min(options_.threads, camera_.height);
  if (threads <= 1) {
    pass.run_rows(0, camera_.height);
    return;
  }
  std::vector<std::thread> workers;
  for (int k = 0; k < threads; ++k) {
    const int r0 = camera_.height * k / threads, r1 = camera_.height * (k + 1) / threads;
    workers.emplace_back([&pass, r0, r1] { pass.run_rows(r0, r1); });
  }
  for (auto& t : workers) t.join();
}

RenderedFrame Renderer::render(const SE3& T_world_cam, std::uint64_t noise_seed) const {
  RenderedFrame f;
  const bool noisy = options_.degradation.enabled;
  render_pass(T_world_cam, noise_seed, noisy, noisy, f.bgr, &f.depth);
  return f;
}

RenderedFrame Renderer::render_moving(const SE3& T_world_cam_prev, const SE3& T_world_cam,
                                      std::uint64_t noise_seed) const {
  const Degradation& deg = options_.degradation;
  if (!deg.enabled || deg.blur_samples <= 1) return render(T_world_cam, noise_seed);
  RenderedFrame f;
  cv::Mat sum(camera_.height, camera_.width, CV_32FC3, cv::Scalar::all(0)), sample, sample_f;
  const int n = deg.blur_samples;
  for (int k = 0; k < n; ++k) {
    const double alpha = 1.0 - deg.blur_exposure * (n - 1 - k) / (n - 1);
    const bool last = k == n - 1;
    render_pass(interpolate_pose(T_world_cam_prev, T_world_cam, alpha), noise_seed, last, false, sample,
                last ? &f.depth : nullptr);
    sample.convertTo(sample_f, CV_32FC3);
    sum += sample_f;
  }
  sum /= static_cast<double>(n);
  // Image noise after averaging, from the same per-pixel hash as render().
  f.bgr.create(camera_.height, camera_.width, CV_8UC3);
  for (int v = 0; v < camera_.height; ++v) {
    const cv::Vec3f* in = sum.ptr<cv::Vec3f>(v);
    cv::Vec3b* out = f.bgr.ptr<cv::Vec3b>(v);
    for (int u = 0; u < camera_.width; ++u) {
      const std::uint64_t h = mix64(noise_seed ^ (static_cast<std::uint64_t>(v) * 0x9E3779B97F4A7C15ull + u));
      for (int k = 0; k < 3; ++k)
        out[u][k] = cv::saturate_cast<uchar>(in[u][k] + static_cast<float>(deg.image_noise_sigma) *
                                                            approx_gauss(mix64(h + 1 + k)));
    }
  }
  return f;
}

}  // namespace cslam::synth
