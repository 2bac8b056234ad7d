// reader.ply: the binary little-endian PLY files writer.ply produces, and similar
// ones (float/double x, y, z, optional colour and normal, triangle faces).
#include "importers/mesh/ply_mesh.hpp"

#include "core/error.hpp"
#include "importers/ply/ply_header.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>

namespace strata {
namespace {

// A colour channel stored as another type than uchar: clamped to 0..255.
std::uint8_t colour_channel(double v) {
  if (!(v > 0)) return 0;
  return v >= 255 ? 255 : static_cast<std::uint8_t>(v);
}

// What the header declares, besides what PlyContents keeps of it.
struct PlyLayout {
  std::vector<ply::Property> vertex_props;
  std::size_t n_vertices = 0, n_faces = 0;
  std::optional<ply::Type> face_count_type, face_index_type;  // of the face list
  // Of the vertex properties: any one colour channel makes room for all three (a
  // file may lack "red" but have "green"); the same for normals.
  bool has_colour = false, has_normal = false;
  std::size_t vertex_bytes = 0;
};

// A PLY file being read: its stream and the errors naming it. The header declares
// the counts; the data must then hold them. Counts and indices are checked before
// they size an allocation or index a vertex: the file may come from another
// program, or be damaged.
class PlyFile {
 public:
  explicit PlyFile(const std::filesystem::path& path) : path_(path), f_(path, std::ios::binary) {
    if (!f_) throw IoError(fmt::format("{}: {}: cannot open", kStage, path.string()));
  }

  IoError fail(const std::string& what) const {
    return IoError(fmt::format("{}: {}: {}", kStage, path_.string(), what));
  }

  PlyLayout read_header(PlyContents& out);
  void check_layout(PlyLayout& layout, PlyContents& out) const;
  void check_counts_fit(const PlyLayout& layout);
  void read_vertices(const PlyLayout& layout, DenseMesh& m);
  void read_faces(const PlyLayout& layout, DenseMesh& m);

 private:
  static constexpr const char* kStage = "reader.ply";

  double read_as_double(ply::Type t);

  std::filesystem::path path_;
  std::ifstream f_;
};

// The header's grammar is ply::read_header's; what this reader adds is what it can
// read: binary little-endian, a vertex element and then a face element with one
// vertex index list.
PlyLayout PlyFile::read_header(PlyContents& out) {
  ply::Header h;
  try {
    h = ply::read_header(f_, kStage, path_);
  } catch (const InputError& e) {
    throw IoError(e.what());  // every refusal of this reader is an IoError
  }
  out.header = h.lines;
  for (const std::string& comment : h.comments) {
    std::istringstream ls(comment);
    std::string what;
    ls >> what;
    if (what == "strata_offset") {
      ls >> out.offset.x() >> out.offset.y() >> out.offset.z();
      out.has_offset_comment = true;
    } else if (what == "crs") {
      ls >> out.crs;
    }
  }
  PlyLayout layout;
  bool seen_vertex = false, seen_face = false;
  for (const ply::Element& e : h.elements) {
    const bool vertex = e.name == "vertex", face = e.name == "face";
    if (!vertex && !face) {
      if (e.count > 0) {
        throw fail(fmt::format("line {}: element '{}' is not supported (vertex and face only)", e.line, e.name));
      }
      continue;
    }
    if ((vertex && (seen_vertex || seen_face)) || (face && seen_face)) {
      throw fail(fmt::format("line {}: element '{}' is not supported here (one vertex element, then one face "
                             "element)", e.line, e.name));
    }
    seen_vertex |= vertex;
    seen_face |= face;
    (vertex ? layout.n_vertices : layout.n_faces) = e.count;
    for (const ply::Property& p : e.properties) {
      if (p.list != face || (face && layout.face_count_type)) {
        throw fail(fmt::format("line {}: unsupported property", p.line));
      }
      if (vertex) {
        layout.vertex_props.push_back(p);
      } else {
        layout.face_count_type = p.count_type;
        layout.face_index_type = p.type;
      }
    }
  }
  if (h.format != ply::Format::binary_little_endian) throw fail("only binary_little_endian PLY is supported");
  return layout;
}

void PlyFile::check_layout(PlyLayout& layout, PlyContents& out) const {
  bool has_x = false, has_y = false, has_z = false;
  for (const auto& p : layout.vertex_props) {
    if (p.name == "x") out.double_coordinates = p.type == ply::Type::float64;
    has_x |= p.name == "x";
    has_y |= p.name == "y";
    has_z |= p.name == "z";
    layout.has_colour |= p.name == "red" || p.name == "green" || p.name == "blue";
    layout.has_normal |= p.name == "nx" || p.name == "ny" || p.name == "nz";
    layout.vertex_bytes += ply::size_of(p.type);
  }
  if (layout.n_vertices > 0 && !(has_x && has_y && has_z)) throw fail("the vertices have no x, y and z");
  if (layout.n_faces > 0 && !layout.face_count_type) throw fail("the faces have no vertex index list");
}

// The declared counts must fit in what follows the header (a face holds at least
// its count and three indices).
void PlyFile::check_counts_fit(const PlyLayout& layout) {
  const auto data_start = f_.tellg();
  f_.seekg(0, std::ios::end);
  const auto data_bytes = static_cast<std::size_t>(f_.tellg() - data_start);
  f_.seekg(data_start);
  const std::size_t face_bytes =
      layout.n_faces > 0 ? ply::size_of(*layout.face_count_type) + 3 * ply::size_of(*layout.face_index_type) : 0;
  if (layout.n_vertices > data_bytes / std::max<std::size_t>(layout.vertex_bytes, 1) ||
      (face_bytes > 0 && layout.n_faces > (data_bytes - layout.n_vertices * layout.vertex_bytes) / face_bytes)) {
    throw fail(fmt::format("the header declares {} vertices and {} faces, more than the file holds",
                           layout.n_vertices, layout.n_faces));
  }
}

double PlyFile::read_as_double(ply::Type t) {
  unsigned char b[8];
  if (!f_.read(reinterpret_cast<char*>(b), static_cast<std::streamsize>(ply::size_of(t)))) throw fail("file ends early");
  return ply::decode(b, t, false);
}

void PlyFile::read_vertices(const PlyLayout& layout, DenseMesh& m) {
  const std::size_t n = layout.n_vertices;
  // Eigen's fixed-size vectors are not zeroed by resize(): a channel or component
  // the file lacks reads as 0.
  m.vertices.assign(n, Eigen::Vector3d::Zero());
  if (layout.has_colour) m.colours.assign(n, Rgb8::Zero());
  if (layout.has_normal) m.normals.assign(n, Eigen::Vector3f::Zero());
  for (std::size_t i = 0; i < n; ++i) {
    for (const auto& p : layout.vertex_props) {
      const double v = read_as_double(p.type);
      if (p.name == "x") m.vertices[i].x() = v;
      else if (p.name == "y") m.vertices[i].y() = v;
      else if (p.name == "z") m.vertices[i].z() = v;
      else if (p.name == "red") m.colours[i][0] = colour_channel(v);
      else if (p.name == "green") m.colours[i][1] = colour_channel(v);
      else if (p.name == "blue") m.colours[i][2] = colour_channel(v);
      else if (p.name == "nx") m.normals[i][0] = static_cast<float>(v);
      else if (p.name == "ny") m.normals[i][1] = static_cast<float>(v);
      else if (p.name == "nz") m.normals[i][2] = static_cast<float>(v);
    }
  }
}

void PlyFile::read_faces(const PlyLayout& layout, DenseMesh& m) {
  m.faces.reserve(layout.n_faces);
  for (std::size_t i = 0; i < layout.n_faces; ++i) {
    const double count = read_as_double(*layout.face_count_type);
    if (count != 3) {
      throw fail(fmt::format("face {} has {} vertices, only triangles are supported", i, count));
    }
    std::array<int, 3> tri{};
    for (int k = 0; k < 3; ++k) {
      const double index = read_as_double(*layout.face_index_type);
      if (!(index >= 0 && index < static_cast<double>(layout.n_vertices)) || index != std::floor(index) ||
          index > std::numeric_limits<int>::max()) {
        throw fail(fmt::format("face {} names vertex {}, but there are {} vertices", i, index, layout.n_vertices));
      }
      tri[k] = static_cast<int>(index);
    }
    m.faces.push_back(tri);
  }
}

}  // namespace

PlyContents read_ply(const std::filesystem::path& path) {
  PlyFile file(path);
  PlyContents out;
  PlyLayout layout = file.read_header(out);
  file.check_layout(layout, out);
  file.check_counts_fit(layout);
  file.read_vertices(layout, out.mesh);
  file.read_faces(layout, out.mesh);
  return out;
}

}  // namespace strata
