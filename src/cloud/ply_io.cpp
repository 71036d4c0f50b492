#include "cloud/ply_io.h"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "core/error.h"

namespace cslam {

namespace {

// ---------------------------------------------------------------- writing

class AtomicFile {
 public:
  explicit AtomicFile(const std::string& path) : path_(path), tmp_(path + ".tmp") {
    out_.open(tmp_, std::ios::binary | std::ios::trunc);
    if (!out_) throw InputError(path, "cannot open for writing");
  }
  std::ofstream& stream() { return out_; }
  void commit() {
    out_.close();
    if (!out_) throw InputError(path_, "write failed");
    std::error_code ec;
    std::filesystem::rename(tmp_, path_, ec);
    if (ec) throw InputError(path_, "cannot rename temporary file: " + ec.message());
  }
  ~AtomicFile() {
    if (out_.is_open()) {
      out_.close();
      std::remove(tmp_.c_str());
    }
  }

 private:
  std::string path_, tmp_;
  std::ofstream out_;
};

template <typename T>
void put(std::string& buf, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  buf.append(b, sizeof(T));
}

void write_vertices(std::ostream& out, const std::vector<Eigen::Vector3f>& points, const std::vector<Rgb8>& colors,
                    const std::vector<Eigen::Vector3f>& normals) {
  std::string buf;
  const size_t stride = 12 + (normals.empty() ? 0 : 12) + (colors.empty() ? 0 : 3);
  buf.reserve(stride * 65536);
  for (size_t i = 0; i < points.size(); ++i) {
    for (int k = 0; k < 3; ++k) put<float>(buf, points[i][k]);
    if (!normals.empty())
      for (int k = 0; k < 3; ++k) put<float>(buf, normals[i][k]);
    if (!colors.empty()) buf.append(reinterpret_cast<const char*>(colors[i].data()), 3);
    if (buf.size() > stride * 65000) {
      out.write(buf.data(), std::streamsize(buf.size()));
      buf.clear();
    }
  }
  out.write(buf.data(), std::streamsize(buf.size()));
}

std::string vertex_header(size_t n, bool normals, bool colors) {
  std::ostringstream h;
  h << "ply\nformat binary_little_endian 1.0\ncomment written by cslam\nelement vertex " << n << "\n"
    << "property float x\nproperty float y\nproperty float z\n";
  if (normals) h << "property float nx\nproperty float ny\nproperty float nz\n";
  if (colors) h << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  return h.str();
}

void write_ply_body(std::ostream& out, const ColoredCloud& cloud) {
  out << vertex_header(cloud.size(), cloud.has_normals(), cloud.has_colors()) << "end_header\n";
  write_vertices(out, cloud.points, cloud.colors, cloud.normals);
}

void write_ply_mesh_body(std::ostream& out, const TriangleMesh& mesh) {
  out << vertex_header(mesh.vertices.size(), false, !mesh.colors.empty()) << "element face " << mesh.triangles.size()
      << "\nproperty list uchar int vertex_indices\nend_header\n";
  write_vertices(out, mesh.vertices, mesh.colors, {});
  std::string buf;
  buf.reserve(13 * mesh.triangles.size());
  for (const auto& t : mesh.triangles) {
    put<std::uint8_t>(buf, 3);
    for (auto v : t) put<std::int32_t>(buf, std::int32_t(v));
  }
  out.write(buf.data(), std::streamsize(buf.size()));
}

// ---------------------------------------------------------------- reading

enum class PType { kI8, kU8, kI16, kU16, kI32, kU32, kF32, kF64 };

PType parse_type(const std::string& t, const std::string& path) {
  if (t == "char" || t == "int8") return PType::kI8;
  if (t == "uchar" || t == "uint8") return PType::kU8;
  if (t == "short" || t == "int16") return PType::kI16;
  if (t == "ushort" || t == "uint16") return PType::kU16;
  if (t == "int" || t == "int32") return PType::kI32;
  if (t == "uint" || t == "uint32") return PType::kU32;
  if (t == "float" || t == "float32") return PType::kF32;
  if (t == "double" || t == "float64") return PType::kF64;
  throw InputError(path, "unknown PLY property type '" + t + "'");
}

size_t type_size(PType t) {
  switch (t) {
    case PType::kI8:
    case PType::kU8:
      return 1;
    case PType::kI16:
    case PType::kU16:
      return 2;
    case PType::kI32:
    case PType::kU32:
    case PType::kF32:
      return 4;
    case PType::kF64:
      return 8;
  }
  return 0;
}

double read_binary(const char* p, PType t) {
  switch (t) {
    case PType::kI8: {
      std::int8_t v;
      std::memcpy(&v, p, 1);
      return v;
    }
    case PType::kU8: {
      std::uint8_t v;
      std::memcpy(&v, p, 1);
      return v;
    }
    case PType::kI16: {
      std::int16_t v;
      std::memcpy(&v, p, 2);
      return v;
    }
    case PType::kU16: {
      std::uint16_t v;
      std::memcpy(&v, p, 2);
      return v;
    }
    case PType::kI32: {
      std::int32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case PType::kU32: {
      std::uint32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case PType::kF32: {
      float v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case PType::kF64: {
      double v;
      std::memcpy(&v, p, 8);
      return v;
    }
  }
  return 0;
}

struct Property {
  std::string name;
  PType type = PType::kF32;
  bool is_list = false;
  PType count_type = PType::kU8;
};
struct Element {
  std::string name;
  size_t count = 0;
  std::vector<Property> props;
};

struct PlyContent {
  ColoredCloud cloud;
  std::vector<std::array<std::uint32_t, 3>> triangles;
};

// Reads one element instance's values: scalars go to `values`, the (single) list to `list`.
class ElementReader {
 public:
  ElementReader(std::istream& in, bool binary, const std::string& path) : in_(in), binary_(binary), path_(path) {}

  void read(const Element& e, std::vector<double>& values, std::vector<double>& list) {
    values.resize(e.props.size());
    list.clear();
    if (!binary_) {
      if (!std::getline(in_, line_)) throw InputError(path_, "file ends inside element '" + e.name + "'");
      std::istringstream ls(line_);
      for (size_t k = 0; k < e.props.size(); ++k) {
        double v = 0;
        if (!(ls >> v)) throw InputError(path_, "malformed ASCII line in element '" + e.name + "'");
        values[k] = v;
        if (e.props[k].is_list) {
          const long n = long(v);
          if (n < 0) throw InputError(path_, "negative list length");
          for (long i = 0; i < n; ++i) {
            if (!(ls >> v)) throw InputError(path_, "malformed ASCII list in element '" + e.name + "'");
            list.push_back(v);
          }
        }
      }
      return;
    }
    char b[8];
    for (size_t k = 0; k < e.props.size(); ++k) {
      const Property& p = e.props[k];
      const PType t = p.is_list ? p.count_type : p.type;
      if (!in_.read(b, std::streamsize(type_size(t))))
        throw InputError(path_, "file ends inside element '" + e.name + "'");
      values[k] = read_binary(b, t);
      if (p.is_list) {
        const long n = long(values[k]);
        if (n < 0 || n > 1000) throw InputError(path_, "implausible list length " + std::to_string(n));
        for (long i = 0; i < n; ++i) {
          if (!in_.read(b, std::streamsize(type_size(p.type)))) throw InputError(path_, "file ends inside a list");
          list.push_back(read_binary(b, p.type));
        }
      }
    }
  }

 private:
  std::istream& in_;
  bool binary_;
  std::string path_, line_;
};

int find_prop(const Element& e, std::initializer_list<const char*> names) {
  for (const char* n : names)
    for (size_t k = 0; k < e.props.size(); ++k)
      if (e.props[k].name == n) return int(k);
  return -1;
}

PlyContent read_ply_file(const std::string& path, bool want_faces) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open PLY file");
  std::string line;
  if (!std::getline(in, line) || line.substr(0, 3) != "ply")
    throw InputError(path, "not a PLY file (missing 'ply' magic)");
  bool binary = false, have_format = false;
  std::vector<Element> elements;
  while (true) {
    if (!std::getline(in, line)) throw InputError(path, "PLY header has no end_header");
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string kw;
    ls >> kw;
    if (kw == "end_header") break;
    if (kw == "comment" || kw == "obj_info" || kw.empty()) continue;
    if (kw == "format") {
      std::string f;
      ls >> f;
      if (f == "ascii")
        binary = false;
      else if (f == "binary_little_endian")
        binary = true;
      else
        throw InputError(path, "unsupported PLY format '" + f + "' (ascii or binary_little_endian)");
      have_format = true;
    } else if (kw == "element") {
      Element e;
      long long n = -1;
      ls >> e.name >> n;
      if (n < 0) throw InputError(path, "malformed element line: " + line);
      e.count = size_t(n);
      elements.push_back(e);
    } else if (kw == "property") {
      if (elements.empty()) throw InputError(path, "property before any element");
      Property p;
      std::string t;
      ls >> t;
      if (t == "list") {
        std::string ct, it;
        ls >> ct >> it >> p.name;
        p.is_list = true;
        p.count_type = parse_type(ct, path);
        p.type = parse_type(it, path);
      } else {
        p.type = parse_type(t, path);
        ls >> p.name;
      }
      elements.back().props.push_back(p);
    } else {
      throw InputError(path, "unexpected PLY header line: " + line);
    }
  }
  if (!have_format) throw InputError(path, "PLY header has no format line");

  PlyContent out;
  bool have_vertex = false;
  ElementReader reader(in, binary, path);
  std::vector<double> values, list;
  for (const Element& e : elements) {
    const bool is_vertex = e.name == "vertex", is_face = e.name == "face";
    if (!is_vertex && !(is_face && want_faces)) {
      if (have_vertex && !want_faces) break;  // nothing more needed
      for (size_t i = 0; i < e.count; ++i) reader.read(e, values, list);
      continue;
    }
    if (is_vertex) {
      have_vertex = true;
      const int ix = find_prop(e, {"x"}), iy = find_prop(e, {"y"}), iz = find_prop(e, {"z"});
      if (ix < 0 || iy < 0 || iz < 0) throw InputError(path, "vertex element lacks x, y or z");
      const int ir = find_prop(e, {"red", "r", "diffuse_red"}), ig = find_prop(e, {"green", "g", "diffuse_green"}),
                ib = find_prop(e, {"blue", "b", "diffuse_blue"});
      const int inx = find_prop(e, {"nx"}), iny = find_prop(e, {"ny"}), inz = find_prop(e, {"nz"});
      const bool colors = ir >= 0 && ig >= 0 && ib >= 0, normals = inx >= 0 && iny >= 0 && inz >= 0;
      auto& c = out.cloud;
      c.points.reserve(e.count);
      if (colors) c.colors.reserve(e.count);
      if (normals) c.normals.reserve(e.count);
      for (size_t i = 0; i < e.count; ++i) {
        reader.read(e, values, list);
        c.points.emplace_back(float(values[ix]), float(values[iy]), float(values[iz]));
        if (colors) {
          // Float colours (0..1) are scaled to bytes.
          const bool unit = e.props[ir].type == PType::kF32 || e.props[ir].type == PType::kF64;
          auto byte = [&](double v) { return std::uint8_t(std::clamp(unit ? v * 255.0 + 0.5 : v, 0.0, 255.0)); };
          c.colors.push_back({byte(values[ir]), byte(values[ig]), byte(values[ib])});
        }
        if (normals) c.normals.emplace_back(float(values[inx]), float(values[iny]), float(values[inz]));
      }
    } else {
      const int il = find_prop(e, {"vertex_indices", "vertex_index"});
      if (il < 0 || !e.props[il].is_list) throw InputError(path, "face element lacks a vertex_indices list");
      for (size_t i = 0; i < e.count; ++i) {
        reader.read(e, values, list);
        for (size_t k = 2; k < list.size(); ++k)
          out.triangles.push_back({std::uint32_t(list[0]), std::uint32_t(list[k - 1]), std::uint32_t(list[k])});
      }
    }
  }
  if (!have_vertex) throw InputError(path, "PLY file has no vertex element");
  for (const auto& t : out.triangles)
    for (auto v : t)
      if (v >= out.cloud.points.size())
        throw InputError(path, "face refers to vertex " + std::to_string(v) + " out of range");
  return out;
}

// The checks every writer makes, file or memory: `target` names where the bytes were going.
void check_cloud(const ColoredCloud& cloud, const std::string& target) {
  if (cloud.empty()) throw std::invalid_argument("refusing to write an empty point cloud to " + target);
  if (cloud.has_colors() && cloud.colors.size() != cloud.size())
    throw std::invalid_argument("PLY " + target + ": colour count differs from point count");
  if (cloud.has_normals() && cloud.normals.size() != cloud.size())
    throw std::invalid_argument("PLY " + target + ": normal count differs from point count");
}

void check_mesh(const TriangleMesh& mesh, const std::string& target) {
  if (mesh.vertices.empty() || mesh.triangles.empty())
    throw std::invalid_argument("refusing to write an empty mesh to " + target);
  if (!mesh.colors.empty() && mesh.colors.size() != mesh.vertices.size())
    throw std::invalid_argument("PLY " + target + ": colour count differs from vertex count");
  for (const auto& t : mesh.triangles)
    for (const auto v : t)
      if (v >= mesh.vertices.size())
        throw std::invalid_argument("PLY " + target + ": a triangle refers to vertex " + std::to_string(v) + " of " +
                                    std::to_string(mesh.vertices.size()));
}

}  // namespace

void write_ply(const std::string& path, const ColoredCloud& cloud) {
  check_cloud(cloud, path);
  AtomicFile f(path);
  write_ply_body(f.stream(), cloud);
  f.commit();
}

void write_ply_mesh(const std::string& path, const TriangleMesh& mesh) {
  check_mesh(mesh, path);
  AtomicFile f(path);
  write_ply_mesh_body(f.stream(), mesh);
  f.commit();
}

std::string ply_bytes(const ColoredCloud& cloud) {
  check_cloud(cloud, "bytes in memory");
  std::ostringstream out;
  write_ply_body(out, cloud);
  return std::move(out).str();
}

std::string ply_mesh_bytes(const TriangleMesh& mesh) {
  check_mesh(mesh, "bytes in memory");
  std::ostringstream out;
  write_ply_mesh_body(out, mesh);
  return std::move(out).str();
}

ColoredCloud read_ply(const std::string& path) { return read_ply_file(path, false).cloud; }

TriangleMesh read_ply_mesh(const std::string& path) {
  PlyContent c = read_ply_file(path, true);
  TriangleMesh m;
  m.vertices = std::move(c.cloud.points);
  m.colors = std::move(c.cloud.colors);
  m.triangles = std::move(c.triangles);
  return m;
}

}  // namespace cslam
