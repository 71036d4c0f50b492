// PLY / PCD reading and writing: round trips, the synthetic generator's scene.ply layout,
// ASCII input, and refusal of empty or malformed data.
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "cloud/pcd_io.h"
#include "common/run_program.h"
#include "cloud/ply_io.h"
#include "core/error.h"

using namespace cslam;
namespace fs = std::filesystem;

namespace {

std::string temp_path(const std::string& name) {
  static const test::TempDir dir("cslam_cloud_io");  // removed at exit
  return dir / name;
}

ColoredCloud sample_cloud() {
  ColoredCloud c;
  for (int i = 0; i < 100; ++i) {
    c.points.emplace_back(0.1f * i, -0.5f * i, 3.25f + i);
    c.colors.push_back({std::uint8_t(i), std::uint8_t(255 - i), std::uint8_t(2 * i)});
  }
  return c;
}

}  // namespace

TEST(PlyIo, BinaryRoundTripKeepsPointsAndColours) {
  const ColoredCloud c = sample_cloud();
  const std::string path = temp_path("rt.ply");
  write_ply(path, c);
  const ColoredCloud r = read_ply(path);
  ASSERT_EQ(r.size(), c.size());
  ASSERT_TRUE(r.has_colors());
  EXPECT_FALSE(r.has_normals());
  for (size_t i = 0; i < c.size(); ++i) {
    EXPECT_EQ(r.points[i], c.points[i]);
    EXPECT_EQ(r.colors[i], c.colors[i]);
  }
  EXPECT_FALSE(fs::exists(path + ".tmp"));
}

TEST(PlyIo, ReadsSceneLayoutWithNormalsAfterColours) {
  // The synthetic generator's scene.ply: float x y z, uchar red green blue, float nx ny nz.
  const std::string path = temp_path("scene.ply");
  {
    std::ofstream f(path, std::ios::binary);
    f << "ply\nformat binary_little_endian 1.0\ncomment synthetic\nelement vertex 2\nproperty float x\nproperty float "
         "y\n"
         "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nproperty float nx\n"
         "property float ny\nproperty float nz\nend_header\n";
    const float xyz[2][3] = {{1, 2, 3}, {-4, 5.5f, 6}};
    const unsigned char rgb[2][3] = {{10, 20, 30}, {200, 210, 220}};
    const float n[2][3] = {{0, 0, 1}, {1, 0, 0}};
    for (int i = 0; i < 2; ++i) {
      f.write(reinterpret_cast<const char*>(xyz[i]), 12);
      f.write(reinterpret_cast<const char*>(rgb[i]), 3);
      f.write(reinterpret_cast<const char*>(n[i]), 12);
    }
  }
  const ColoredCloud r = read_ply(path);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_EQ(r.points[1], Eigen::Vector3f(-4, 5.5f, 6));
  EXPECT_EQ(r.colors[1], (Rgb8{200, 210, 220}));
  ASSERT_TRUE(r.has_normals());
  EXPECT_EQ(r.normals[1], Eigen::Vector3f(1, 0, 0));
}

TEST(PlyIo, ReadsAsciiAndSkipsOtherElements) {
  const std::string path = temp_path("ascii.ply");
  {
    std::ofstream f(path);
    f << "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\n"
         "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1.5 0\n3 0 1 2\n";
  }
  const ColoredCloud r = read_ply(path);
  ASSERT_EQ(r.size(), 3u);
  EXPECT_FALSE(r.has_colors());
  EXPECT_FLOAT_EQ(r.points[2].y(), 1.5f);
  const TriangleMesh m = read_ply_mesh(path);
  ASSERT_EQ(m.triangles.size(), 1u);
  EXPECT_EQ(m.triangles[0], (std::array<std::uint32_t, 3>{0, 1, 2}));
}

TEST(PlyIo, MeshRoundTrip) {
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.colors = {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}, {10, 11, 12}};
  m.triangles = {{0, 1, 2}, {0, 3, 1}};
  const std::string path = temp_path("mesh.ply");
  write_ply_mesh(path, m);
  const TriangleMesh r = read_ply_mesh(path);
  EXPECT_EQ(r.vertices, m.vertices);
  EXPECT_EQ(r.colors, m.colors);
  EXPECT_EQ(r.triangles, m.triangles);
}

// The file and the in-memory writers refuse the same inconsistent inputs (the in-memory ones serve
// HTTP downloads): what one would write, a reader would reject or read past.
TEST(PlyIo, EveryWriterRefusesInconsistentCountsAndIndices) {
  ColoredCloud few_colours = sample_cloud();
  few_colours.colors.pop_back();
  EXPECT_THROW(write_ply(temp_path("c.ply"), few_colours), std::invalid_argument);
  EXPECT_THROW(ply_bytes(few_colours), std::invalid_argument);
  ColoredCloud few_normals = sample_cloud();
  few_normals.normals.assign(few_normals.size() - 1, Eigen::Vector3f::UnitZ());
  EXPECT_THROW(write_ply(temp_path("n.ply"), few_normals), std::invalid_argument);
  EXPECT_THROW(ply_bytes(few_normals), std::invalid_argument);
  EXPECT_THROW(ply_bytes(ColoredCloud{}), std::invalid_argument);
  EXPECT_EQ(ply_bytes(sample_cloud()).rfind("ply\n", 0), 0u);

  TriangleMesh mesh;
  mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  mesh.triangles = {{0, 1, 2}};
  EXPECT_NO_THROW(ply_mesh_bytes(mesh));
  TriangleMesh out_of_range = mesh;
  out_of_range.triangles.push_back({0, 2, 3});
  EXPECT_THROW(write_ply_mesh(temp_path("m.ply"), out_of_range), std::invalid_argument);
  EXPECT_THROW(ply_mesh_bytes(out_of_range), std::invalid_argument);
  TriangleMesh few_mesh_colours = mesh;
  few_mesh_colours.colors = {{1, 2, 3}};
  EXPECT_THROW(write_ply_mesh(temp_path("m.ply"), few_mesh_colours), std::invalid_argument);
  EXPECT_THROW(ply_mesh_bytes(few_mesh_colours), std::invalid_argument);
  EXPECT_FALSE(fs::exists(temp_path("c.ply")) || fs::exists(temp_path("n.ply")) || fs::exists(temp_path("m.ply")));
}

TEST(PlyIo, RefusesEmptyAndRejectsMalformed) {
  EXPECT_THROW(write_ply(temp_path("empty.ply"), ColoredCloud{}), std::invalid_argument);
  EXPECT_FALSE(fs::exists(temp_path("empty.ply")));
  EXPECT_THROW(write_pcd(temp_path("empty.pcd"), ColoredCloud{}), std::invalid_argument);
  EXPECT_THROW(read_ply(temp_path("does_not_exist.ply")), InputError);
  const std::string bad = temp_path("bad.ply");
  {
    std::ofstream f(bad, std::ios::binary);
    f << "ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty float x\nend_header\n";
  }
  EXPECT_THROW(read_ply(bad), InputError);
  {
    std::ofstream f(bad, std::ios::binary);
    f << "ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float "
         "z\nend_header\n";
    const float xyz[3] = {1, 2, 3};
    f.write(reinterpret_cast<const char*>(xyz), 12);  // 1 of 5 vertices
  }
  try {
    read_ply(bad);
    FAIL() << "truncated file accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.ply"), std::string::npos) << e.what();
  }
}

TEST(PcdIo, BinaryHeaderAndPayload) {
  const ColoredCloud c = sample_cloud();
  const std::string path = temp_path("c.pcd");
  write_pcd(path, c, true);
  std::ifstream f(path, std::ios::binary);
  std::string line, header;
  while (std::getline(f, line)) {
    header += line + "\n";
    if (line.rfind("DATA", 0) == 0) break;
  }
  EXPECT_NE(header.find("FIELDS x y z rgb"), std::string::npos);
  EXPECT_NE(header.find("POINTS 100"), std::string::npos);
  EXPECT_NE(header.find("DATA binary"), std::string::npos);
  char rec[16];
  for (int i = 0; i < 4; ++i) f.read(rec, 16);  // 4th point (i = 3)
  ASSERT_TRUE(f);
  float xyz[3];
  std::uint32_t rgb;
  std::memcpy(xyz, rec, 12);
  std::memcpy(&rgb, rec + 12, 4);
  EXPECT_FLOAT_EQ(xyz[2], 3.25f + 3);
  EXPECT_EQ(rgb, (3u << 16) | (252u << 8) | 6u);
  write_pcd(temp_path("a.pcd"), c, false);
  std::ifstream a(temp_path("a.pcd"));
  int lines = 0;
  while (std::getline(a, line)) ++lines;
  EXPECT_EQ(lines, 11 + 100);
}
