#include "dense/marching_cubes.h"

#include <stdexcept>

namespace cslam {

namespace {

int edge_between(int c0, int c1) {
  const int diff = c0 ^ c1;
  const int axis = diff == 1 ? 0 : diff == 2 ? 1 : diff == 4 ? 2 : -1;
  if (axis < 0) throw std::logic_error("marching cubes: corners are not adjacent");
  const int low = c0 & ~diff;  // the end with the axis bit cleared
  // j enumerates the corners with bit `axis` clear, in increasing order.
  int j = 0;
  for (int c = 0; c < low; ++c)
    if (!(c & diff)) ++j;
  return 4 * axis + j;
}

struct Tables {
  std::array<std::vector<McTriangle>, 256> tris;
  std::array<std::array<int, 2>, 12> edge_corners{};

  Tables() {
    for (int axis = 0; axis < 3; ++axis) {
      int j = 0;
      for (int c = 0; c < 8; ++c)
        if (!(c & (1 << axis))) {
          edge_corners[4 * axis + j] = {c, c | (1 << axis)};
          ++j;
        }
    }
    // Faces with corners counter-clockwise seen from outside the cube.
    std::array<std::array<int, 4>, 6> faces{};
    for (int k = 0; k < 3; ++k) {
      const int a = (k + 1) % 3, b = (k + 2) % 3;
      for (int s = 0; s < 2; ++s) {
        std::array<int, 4> q{};
        const int uv[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};  // CCW about +k since (a, b, k) is cyclic
        for (int i = 0; i < 4; ++i) q[i] = (s << k) | (uv[i][0] << a) | (uv[i][1] << b);
        if (s == 0) std::swap(q[1], q[3]);  // seen from -k: reverse
        faces[2 * k + s] = q;
      }
    }
    for (int config = 0; config < 256; ++config) {
      auto inside = [&](int c) { return (config >> c) & 1; };
      std::array<int, 12> next;
      next.fill(-1);
      for (const auto& q : faces) {
        for (int i = 0; i < 4; ++i) {
          const bool entry = !inside(q[i]) && inside(q[(i + 1) % 4]);
          if (!entry) continue;
          // Walk the inside run to its exit; the segment goes exit -> entry.
          for (int step = 1; step < 4; ++step) {
            const int j = (i + step) % 4;
            if (inside(q[j]) && !inside(q[(j + 1) % 4])) {
              next[edge_between(q[j], q[(j + 1) % 4])] = edge_between(q[i], q[(i + 1) % 4]);
              break;
            }
          }
        }
      }
      std::array<bool, 12> used{};
      for (int start = 0; start < 12; ++start) {
        if (next[start] < 0 || used[start]) continue;
        std::vector<int> loop;
        for (int e = start; !used[e]; e = next[e]) {
          if (next[e] < 0) throw std::logic_error("marching cubes: open iso-line loop");
          used[e] = true;
          loop.push_back(e);
        }
        for (size_t k = 1; k + 1 < loop.size(); ++k) tris[config].push_back({loop[0], loop[k + 1], loop[k]});
      }
    }
  }
};

const Tables& tables() {
  static const Tables t;  // immutable after construction (thread-safe initialisation)
  return t;
}

}  // namespace

const std::vector<McTriangle>& mc_triangles(int config) { return tables().tris.at(size_t(config)); }
int mc_edge_corner(int edge, int end) { return tables().edge_corners.at(size_t(edge))[size_t(end)]; }
int mc_edge_axis(int edge) { return edge / 4; }

}  // namespace cslam
