#pragma once
// The procedural indoor scene of the synthetic RGB-D generator: an axis-aligned room (floor at
// z = 0, z up, walls at x = 0, x = width, y = 0, y = depth) with boxes and cylinders on the floor.
// Every surface is a textured planar face; cylinders are regular prisms (default 48 sides) with a
// disc cap, so renderer, surface sampling and geometry tests share one exact geometry.
// Lambertian shading is baked into the per-surface textures at creation (it does not depend on
// the viewpoint), so rendering is a texture lookup.
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

namespace cslam::synth {

struct SceneConfig {
  std::uint64_t seed = 1;
  double width = 8.0, depth = 6.0, height = 3.0;  // room size in metres (x, y, z)
  int furniture = 10;                             // number of boxes + cylinders
  double cylinder_fraction = 0.35;                // share of furniture that are cylinders
  int cylinder_sides = 48;                        // prism sides approximating a cylinder
  double texel_size = 0.005;                      // metres per texel of the surface textures
  // The walkway: an ellipse centred in the room, `walkway_margin` from the walls, where the robots
  // move. Furniture keeps `furniture_clearance` away from it.
  double walkway_margin = 1.8;
  double furniture_clearance = 0.7;
  // A 1.2 m x 0.9 m texture patch copied onto two different walls (place-recognition trap).
  bool repeat_texture = false;
  // Non-zero: a 1.2 m x 0.9 m poster generated from this seed alone is put every ~2 m along both
  // long walls, so
  // rooms of different seeds given the same poster seed share that texture (cross-room trap).
  std::uint64_t shared_poster_seed = 0;
  double ambient = 0.45;  // ambient share of the lighting, the rest is Lambertian from point lights

  // Throws ConfigError naming the first impossible value.
  void validate() const;
};

struct Texture {
  std::vector<cv::Mat> mip;  // CV_8UC3 BGR, level 0 has texel_size, each next level half the size
};

// A planar rectangle (or the disc inscribed in it) seen from the side its normal points to.
// Points: origin + s * axis_u + t * axis_v, s in [0, size_u], t in [0, size_v].
struct Face {
  Eigen::Vector3d origin, axis_u, axis_v, normal;  // unit axes, normal = axis_u x axis_v
  double size_u = 0, size_v = 0;
  bool disc = false;              // only the disc inscribed in the rectangle exists
  int texture = 0;                // index into Scene::textures
  double tex_u0 = 0, tex_v0 = 0;  // texture coordinates (metres) of the face origin
  int object = -1;                // -1: room, otherwise index into Scene::furniture
  std::string name;

  // True if (s, t) lies on the face.
  bool contains(double s, double t) const {
    if (s < 0 || t < 0 || s > size_u || t > size_v) return false;
    if (!disc) return true;
    const double ds = s - 0.5 * size_u, dt = t - 0.5 * size_v;
    return ds * ds + dt * dt <= 0.25 * size_u * size_u;
  }
  Eigen::Vector3d point(double s, double t) const { return origin + s * axis_u + t * axis_v; }
};

struct Furniture {
  enum class Kind { Box, Cylinder };
  Kind kind = Kind::Box;
  Eigen::Vector2d center{0, 0};   // on the floor
  double half_x = 0, half_y = 0;  // box half sizes
  double radius = 0;              // cylinder circumradius
  double height = 0;
  // 2D distance from a floor point to the footprint (0 inside).
  double footprint_distance(const Eigen::Vector2d& p) const;
};

struct Walkway {
  Eigen::Vector2d center{0, 0};
  double a = 0, b = 0;  // semi-axes along x and y
  // Point on the ellipse at parameter phi.
  Eigen::Vector2d at(double phi) const;
};

// Where the repeated texture patch was placed (two copies), in world coordinates.
struct RepeatedPatch {
  int face_a = -1, face_b = -1;
  Eigen::Vector3d center_a{0, 0, 0}, center_b{0, 0, 0};
  double size_u = 0, size_v = 0;
};

struct Light {
  Eigen::Vector3d position;
  double intensity = 1.0;
};

struct Scene {
  SceneConfig config;
  std::vector<Face> faces;
  std::vector<Texture> textures;
  std::vector<Furniture> furniture;
  std::vector<Light> lights;
  Walkway walkway;
  std::vector<RepeatedPatch> repeated_patches;
  std::vector<Eigen::Vector3d> shared_posters;  // centres of the --shared-poster copies

  // True if p is inside the room and outside every piece of furniture.
  bool is_free(const Eigen::Vector3d& p) const;
  // Smallest distance from p to any face (exact, point-to-rectangle / disc).
  double distance_to_surface(const Eigen::Vector3d& p) const;
  // Shaded colour (BGR) of a face at (s, t) from the finest texture level (bilinear).
  cv::Vec3b color_at(const Face& face, double s, double t) const;
};

// Builds the room, places the furniture (outside the walkway), generates the textures and bakes
// the lighting. Deterministic in config (same config -> identical scene). Throws ConfigError on an
// impossible configuration (negative size, room too small for the walkway, furniture not placeable).
Scene make_scene(const SceneConfig& config);

}  // namespace cslam::synth
