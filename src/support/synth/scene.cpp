#include "support/synth/scene.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "support/synth/random.h"
#include "support/synth/texture.h"

namespace cslam::synth {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::string fmt(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// A vertical rectangle standing on the floor line through `bottom_center`, facing `normal`.
Face vertical_face(const Eigen::Vector3d& bottom_center, const Eigen::Vector3d& normal, double width, double height) {
  Face f;
  f.normal = normal.normalized();
  f.axis_v = Eigen::Vector3d::UnitZ();
  f.axis_u = f.axis_v.cross(f.normal);  // so that axis_u x axis_v = normal
  f.origin = bottom_center - 0.5 * width * f.axis_u;
  f.size_u = width;
  f.size_v = height;
  return f;
}

// A horizontal rectangle [x0, x0+sx] x [y0, y0+sy] at height z, facing up or down.
Face horizontal_face(double x0, double y0, double z, double sx, double sy, bool up) {
  Face f;
  if (up) {
    f.axis_u = Eigen::Vector3d::UnitX();
    f.axis_v = Eigen::Vector3d::UnitY();
    f.size_u = sx;
    f.size_v = sy;
  } else {
    f.axis_u = Eigen::Vector3d::UnitY();
    f.axis_v = Eigen::Vector3d::UnitX();
    f.size_u = sy;
    f.size_v = sx;
  }
  f.normal = f.axis_u.cross(f.axis_v);
  f.origin = Eigen::Vector3d(x0, y0, z);
  return f;
}

double rect_distance_2d(const Eigen::Vector2d& d, double hx, double hy) {
  const double dx = std::max(std::abs(d.x()) - hx, 0.0), dy = std::max(std::abs(d.y()) - hy, 0.0);
  return std::hypot(dx, dy);
}

bool inside_ellipse(const Eigen::Vector2d& p, const Eigen::Vector2d& c, double a, double b) {
  const double x = (p.x() - c.x()) / a, y = (p.y() - c.y()) / b;
  return x * x + y * y <= 1.0;
}

// Points on the boundary of a footprint (every ~2 cm) plus its centre.
std::vector<Eigen::Vector2d> footprint_samples(const Furniture& f) {
  std::vector<Eigen::Vector2d> pts{f.center};
  if (f.kind == Furniture::Kind::Cylinder) {
    const int n = std::max(16, static_cast<int>(2 * kPi * f.radius / 0.02));
    for (int i = 0; i < n; ++i)
      pts.push_back(f.center + f.radius * Eigen::Vector2d(std::cos(2 * kPi * i / n), std::sin(2 * kPi * i / n)));
  } else {
    const int nx = std::max(2, static_cast<int>(2 * f.half_x / 0.02)),
              ny = std::max(2, static_cast<int>(2 * f.half_y / 0.02));
    for (int i = 0; i <= nx; ++i)
      for (double sy : {-1.0, 1.0})
        pts.push_back(f.center + Eigen::Vector2d(-f.half_x + 2 * f.half_x * i / nx, sy * f.half_y));
    for (int i = 0; i <= ny; ++i)
      for (double sx : {-1.0, 1.0})
        pts.push_back(f.center + Eigen::Vector2d(sx * f.half_x, -f.half_y + 2 * f.half_y * i / ny));
  }
  return pts;
}

void place_furniture(Scene& scene, Rng& rng) {
  const SceneConfig& c = scene.config;
  const double gap_wall = 0.05, gap_between = 0.15;
  const double max_h = std::min(2.0, c.height - 0.3);
  const double ka = scene.walkway.a + c.furniture_clearance, kb = scene.walkway.b + c.furniture_clearance;
  for (int i = 0; i < c.furniture; ++i) {
    bool placed = false;
    for (int attempt = 0; attempt < 1000 && !placed; ++attempt) {
      Furniture f;
      if (rng.chance(c.cylinder_fraction)) {
        f.kind = Furniture::Kind::Cylinder;
        f.radius = rng.uniform(0.12, 0.35);
        f.half_x = f.half_y = f.radius;
      } else {
        f.half_x = rng.uniform(0.15, 0.45);
        f.half_y = rng.uniform(0.15, 0.45);
      }
      f.height = rng.uniform(0.35, max_h);
      const double x_lo = gap_wall + f.half_x, x_hi = c.width - gap_wall - f.half_x;
      const double y_lo = gap_wall + f.half_y, y_hi = c.depth - gap_wall - f.half_y;
      if (x_lo >= x_hi || y_lo >= y_hi) continue;
      f.center = Eigen::Vector2d(rng.uniform(x_lo, x_hi), rng.uniform(y_lo, y_hi));
      bool ok = true;
      for (const auto& p : footprint_samples(f))
        if (inside_ellipse(p, scene.walkway.center, ka, kb)) ok = false;
      for (const auto& o : scene.furniture)
        if (std::abs(o.center.x() - f.center.x()) < o.half_x + f.half_x + gap_between &&
            std::abs(o.center.y() - f.center.y()) < o.half_y + f.half_y + gap_between)
          ok = false;
      if (ok) {
        scene.furniture.push_back(f);
        placed = true;
      }
    }
    if (!placed)
      throw ConfigError("synth: could place only " + std::to_string(scene.furniture.size()) + " of " +
                        std::to_string(c.furniture) + " furniture items in a " + fmt(c.width) + " x " + fmt(c.depth) +
                        " m room outside the walkway; use fewer --furniture or a larger --room");
  }
}

void add_face(Scene& scene, Face f, const std::string& name, int object, std::uint64_t seed) {
  f.name = name;
  f.object = object;
  f.texture = static_cast<int>(scene.textures.size());
  scene.textures.push_back(Texture{{make_albedo_texture(f.size_u, f.size_v, scene.config.texel_size, seed)}});
  scene.faces.push_back(f);
}

void build_geometry(Scene& scene) {
  const SceneConfig& c = scene.config;
  const double W = c.width, D = c.depth, H = c.height;
  std::uint64_t tag = 0;
  auto seed = [&] { return derive_seed(c.seed, 1000 + tag++); };
  add_face(scene, horizontal_face(0, 0, 0, W, D, true), "floor", -1, seed());
  add_face(scene, horizontal_face(0, 0, H, W, D, false), "ceiling", -1, seed());
  add_face(scene, vertical_face({W / 2, 0, 0}, {0, 1, 0}, W, H), "wall_y0", -1, seed());
  add_face(scene, vertical_face({W, D / 2, 0}, {-1, 0, 0}, D, H), "wall_xmax", -1, seed());
  add_face(scene, vertical_face({W / 2, D, 0}, {0, -1, 0}, W, H), "wall_ymax", -1, seed());
  add_face(scene, vertical_face({0, D / 2, 0}, {1, 0, 0}, D, H), "wall_x0", -1, seed());
  for (size_t i = 0; i < scene.furniture.size(); ++i) {
    const Furniture& f = scene.furniture[i];
    const int obj = static_cast<int>(i);
    const std::string name = (f.kind == Furniture::Kind::Box ? "box" : "cylinder") + std::to_string(i);
    const Eigen::Vector3d c3(f.center.x(), f.center.y(), 0);
    if (f.kind == Furniture::Kind::Box) {
      add_face(scene, vertical_face(c3 + Eigen::Vector3d(f.half_x, 0, 0), {1, 0, 0}, 2 * f.half_y, f.height),
               name + "_xp", obj, seed());
      add_face(scene, vertical_face(c3 - Eigen::Vector3d(f.half_x, 0, 0), {-1, 0, 0}, 2 * f.half_y, f.height),
               name + "_xn", obj, seed());
      add_face(scene, vertical_face(c3 + Eigen::Vector3d(0, f.half_y, 0), {0, 1, 0}, 2 * f.half_x, f.height),
               name + "_yp", obj, seed());
      add_face(scene, vertical_face(c3 - Eigen::Vector3d(0, f.half_y, 0), {0, -1, 0}, 2 * f.half_x, f.height),
               name + "_yn", obj, seed());
      add_face(
          scene,
          horizontal_face(f.center.x() - f.half_x, f.center.y() - f.half_y, f.height, 2 * f.half_x, 2 * f.half_y, true),
          name + "_top", obj, seed());
    } else {
      // Regular prism: all sides share one texture wrapped around the cylinder.
      const int n = c.cylinder_sides;
      const double side = 2 * f.radius * std::sin(kPi / n), apothem = f.radius * std::cos(kPi / n);
      const int tex = static_cast<int>(scene.textures.size());
      scene.textures.push_back(Texture{{make_albedo_texture(side * n, f.height, c.texel_size, seed())}});
      for (int k = 0; k < n; ++k) {
        const double a = 2 * kPi * (k + 0.5) / n;
        const Eigen::Vector3d normal(std::cos(a), std::sin(a), 0);
        Face face = vertical_face(c3 + apothem * normal, normal, side, f.height);
        face.name = name + "_side" + std::to_string(k);
        face.object = obj;
        face.texture = tex;
        face.tex_u0 = side * k;
        scene.faces.push_back(face);
      }
      Face top =
          horizontal_face(f.center.x() - f.radius, f.center.y() - f.radius, f.height, 2 * f.radius, 2 * f.radius, true);
      top.disc = true;
      add_face(scene, top, name + "_top", obj, seed());
    }
  }
}

void add_repeated_patch(Scene& scene, Rng& rng) {
  // Copy a poster-sized patch of wall_y0's texture onto wall_ymax (both long walls).
  const double pu = 1.2, pv = 0.9, texel = scene.config.texel_size;
  const int fa = 2, fb = 4;
  const Face &a = scene.faces[fa], &b = scene.faces[fb];
  if (a.size_u < pu + 0.4 || a.size_v < pv + 0.8) return;
  const double sa = rng.uniform(0.2, a.size_u - pu - 0.2), sb = rng.uniform(0.2, b.size_u - pu - 0.2);
  const double t0 = 0.7;  // bottom edge of the poster, metres above the floor
  const cv::Rect src(static_cast<int>(sa / texel), static_cast<int>(t0 / texel), static_cast<int>(pu / texel),
                     static_cast<int>(pv / texel));
  const cv::Rect dst(static_cast<int>(sb / texel), src.y, src.width, src.height);
  scene.textures[a.texture].mip[0](src).copyTo(scene.textures[b.texture].mip[0](dst));
  RepeatedPatch r;
  r.face_a = fa;
  r.face_b = fb;
  r.center_a = a.point(sa + pu / 2, t0 + pv / 2);
  r.center_b = b.point(sb + pu / 2, t0 + pv / 2);
  r.size_u = pu;
  r.size_v = pv;
  scene.repeated_patches.push_back(r);
}

void add_shared_poster(Scene& scene, Rng& rng) {
  // The same poster (its own seed, independent of the room's) every ~2 m along both long walls,
  // so that robots of any room see it.
  const double pu = 1.2, pv = 0.9, texel = scene.config.texel_size, t0 = 0.7;
  const cv::Mat poster = make_albedo_texture(pu, pv, texel, scene.config.shared_poster_seed);
  for (int fi : {2, 4}) {
    const Face& f = scene.faces[fi];
    if (f.size_u < pu + 0.4 || f.size_v < pv + 0.8) continue;
    cv::Mat& tex = scene.textures[f.texture].mip[0];
    for (double s0 = rng.uniform(0.2, 0.8); s0 + pu + 0.2 <= f.size_u; s0 += 2.0) {
      const cv::Rect dst(static_cast<int>((f.tex_u0 + s0) / texel), static_cast<int>((f.tex_v0 + t0) / texel),
                         poster.cols, poster.rows);
      if ((dst & cv::Rect(0, 0, tex.cols, tex.rows)) != dst) continue;
      poster.copyTo(tex(dst));
      scene.shared_posters.push_back(f.point(s0 + pu / 2, t0 + pv / 2));
    }
  }
}

double irradiance(const Scene& scene, const Eigen::Vector3d& p, const Eigen::Vector3d& n) {
  double sum = 0;
  for (const auto& l : scene.lights) {
    const Eigen::Vector3d d = l.position - p;
    const double dist = d.norm();
    if (dist < 1e-6) continue;
    const double cosine = std::max(0.0, n.dot(d) / dist);
    sum += l.intensity * cosine / (1.0 + (dist / 3.0) * (dist / 3.0));
  }
  const double amb = scene.config.ambient;
  return std::min(1.25, amb + (1.0 - amb) * sum);
}

// Multiplies each face's texture region by its Lambertian irradiance (computed on a coarse grid
// of 4x4 texels and interpolated; lighting is smooth).
void bake_lighting(Scene& scene) {
  const double texel = scene.config.texel_size;
  for (const Face& f : scene.faces) {
    cv::Mat& tex = scene.textures[f.texture].mip[0];
    const int x0 = std::clamp(static_cast<int>(std::lround(f.tex_u0 / texel)), 0, tex.cols - 1);
    const int y0 = std::clamp(static_cast<int>(std::lround(f.tex_v0 / texel)), 0, tex.rows - 1);
    const int x1 = std::clamp(static_cast<int>(std::lround((f.tex_u0 + f.size_u) / texel)), x0 + 1, tex.cols);
    const int y1 = std::clamp(static_cast<int>(std::lround((f.tex_v0 + f.size_v) / texel)), y0 + 1, tex.rows);
    const int w = x1 - x0, h = y1 - y0, step = 4;
    const int gw = w / step + 2, gh = h / step + 2;
    cv::Mat coarse(gh, gw, CV_32F);
    for (int j = 0; j < gh; ++j)
      for (int i = 0; i < gw; ++i) {
        const double s = std::min(f.size_u, i * step * texel), t = std::min(f.size_v, j * step * texel);
        coarse.at<float>(j, i) = static_cast<float>(irradiance(scene, f.point(s, t), f.normal));
      }
    cv::Mat shade;
    cv::resize(coarse, shade, cv::Size(gw * step, gh * step), 0, 0, cv::INTER_LINEAR);
    for (int y = 0; y < h; ++y) {
      auto* row = tex.ptr<cv::Vec3b>(y0 + y) + x0;
      const float* sr = shade.ptr<float>(y);
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) row[x][c] = cv::saturate_cast<uchar>(row[x][c] * sr[x]);
    }
  }
  for (auto& t : scene.textures) t.mip = make_mip_chain(t.mip[0]);
}

}  // namespace

void SceneConfig::validate() const {
  if (!(width > 0) || !(depth > 0) || !(height > 0))
    throw ConfigError("synth: room size must be positive, got " + fmt(width) + " x " + fmt(depth) + " x " +
                      fmt(height) + " m");
  if (height < 2.0) throw ConfigError("synth: room height " + fmt(height) + " m is below 2 m (robots fly up to 1.5 m)");
  if (furniture < 0) throw ConfigError("synth: furniture count must be >= 0, got " + std::to_string(furniture));
  if (!(texel_size >= 0.001 && texel_size <= 0.05)) throw ConfigError("synth: texel_size must be in [0.001, 0.05] m");
  if (cylinder_sides < 8) throw ConfigError("synth: cylinder_sides must be >= 8");
  if (!(walkway_margin > 0.3) || !(furniture_clearance >= 0))
    throw ConfigError("synth: walkway_margin must be > 0.3 m and clearance >= 0");
  if (!(ambient >= 0 && ambient <= 1)) throw ConfigError("synth: ambient must be in [0, 1]");
  if (!(cylinder_fraction >= 0 && cylinder_fraction <= 1))
    throw ConfigError("synth: cylinder_fraction must be in [0, 1]");
  const double a = width / 2 - walkway_margin, b = depth / 2 - walkway_margin;
  if (a < 0.4 || b < 0.4)
    throw ConfigError("synth: a " + fmt(width) + " x " + fmt(depth) +
                      " m room is too small for the robots' trajectories (needs at least " +
                      fmt(2 * (walkway_margin + 0.4)) + " m in both directions)");
}

double Furniture::footprint_distance(const Eigen::Vector2d& p) const {
  if (kind == Kind::Cylinder) return std::max(0.0, (p - center).norm() - radius);
  return rect_distance_2d(p - center, half_x, half_y);
}

Eigen::Vector2d Walkway::at(double phi) const { return center + Eigen::Vector2d(a * std::cos(phi), b * std::sin(phi)); }

bool Scene::is_free(const Eigen::Vector3d& p) const {
  if (p.x() <= 0 || p.y() <= 0 || p.z() <= 0 || p.x() >= config.width || p.y() >= config.depth ||
      p.z() >= config.height)
    return false;
  for (const auto& f : furniture)
    if (p.z() <= f.height && f.footprint_distance(p.head<2>()) <= 0) return false;
  return true;
}

double Scene::distance_to_surface(const Eigen::Vector3d& p) const {
  double best = std::numeric_limits<double>::infinity();
  for (const Face& f : faces) {
    const Eigen::Vector3d d = p - f.origin;
    double s = d.dot(f.axis_u), t = d.dot(f.axis_v);
    if (!f.contains(s, t)) {
      if (f.disc) {
        const double r = 0.5 * f.size_u;
        Eigen::Vector2d q(s - r, t - r);
        q *= r / q.norm();
        s = q.x() + r;
        t = q.y() + r;
      } else {
        s = std::clamp(s, 0.0, f.size_u);
        t = std::clamp(t, 0.0, f.size_v);
      }
    }
    best = std::min(best, (p - f.point(s, t)).norm());
  }
  return best;
}

cv::Vec3b Scene::color_at(const Face& face, double s, double t) const {
  const cv::Mat& tex = textures[face.texture].mip[0];
  const double x = std::clamp((s + face.tex_u0) / config.texel_size - 0.5, 0.0, tex.cols - 1.0);
  const double y = std::clamp((t + face.tex_v0) / config.texel_size - 0.5, 0.0, tex.rows - 1.0);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const int x1 = std::min(x0 + 1, tex.cols - 1), y1 = std::min(y0 + 1, tex.rows - 1);
  const double fx = x - x0, fy = y - y0;
  cv::Vec3b out;
  for (int c = 0; c < 3; ++c) {
    const double top = tex.at<cv::Vec3b>(y0, x0)[c] * (1 - fx) + tex.at<cv::Vec3b>(y0, x1)[c] * fx;
    const double bot = tex.at<cv::Vec3b>(y1, x0)[c] * (1 - fx) + tex.at<cv::Vec3b>(y1, x1)[c] * fx;
    out[c] = cv::saturate_cast<uchar>(top * (1 - fy) + bot * fy);
  }
  return out;
}

Scene make_scene(const SceneConfig& config) {
  config.validate();
  Scene scene;
  scene.config = config;
  scene.walkway.center = Eigen::Vector2d(config.width / 2, config.depth / 2);
  scene.walkway.a = config.width / 2 - config.walkway_margin;
  scene.walkway.b = config.depth / 2 - config.walkway_margin;
  Rng rng(derive_seed(config.seed, 1));
  place_furniture(scene, rng);
  // Three point lights below the ceiling, jittered by the seed.
  const double W = config.width, D = config.depth, H = config.height;
  const double lx[3] = {0.25, 0.75, 0.5}, ly[3] = {0.3, 0.4, 0.75};
  for (int i = 0; i < 3; ++i)
    scene.lights.push_back(
        {Eigen::Vector3d(W * (lx[i] + rng.uniform(-0.1, 0.1)), D * (ly[i] + rng.uniform(-0.1, 0.1)), H - 0.3), 0.75});
  build_geometry(scene);
  if (config.repeat_texture) add_repeated_patch(scene, rng);
  if (config.shared_poster_seed != 0) add_shared_poster(scene, rng);
  bake_lighting(scene);
  return scene;
}

}  // namespace cslam::synth
