// CGAL processing of dense meshes: the only translation unit of the module that
// includes CGAL (its headers are heavy; see docs/dependencies).
#include "core/error.hpp"
#include "dense/dense_mesh.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_simplification/Edge_collapse_visitor_base.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Count_stop_predicate.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>
#include <CGAL/boost/graph/helpers.h>

#include <cmath>
#include <vector>

namespace strata {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using CgalMesh = CGAL::Surface_mesh<Point>;
namespace PMP = CGAL::Polygon_mesh_processing;

// orient_polygon_soup duplicates a non-manifold vertex; the copy is a new point at the
// end, and keeps the attributes of the vertex it copies.
struct DuplicateSources : CGAL::Polygon_mesh_processing::Default_orientation_visitor {
  std::vector<std::size_t>* source = nullptr;  // per point: the input vertex it stands for
  void duplicated_vertex(std::size_t from, std::size_t copy) {
    if (source->size() <= copy) source->resize(copy + 1);
    (*source)[copy] = (*source)[from];
  }
};

// Builds a CGAL surface mesh from the triangle soup; orient_polygon_soup splits
// non-manifold vertices/edges (marching-cubes output may have a few), so that the
// halfedge structure is always valid. `source`, when given, receives for each CGAL
// vertex index the input vertex it was made from (the soup's points become the
// mesh's vertices in order, isolated ones included).
CgalMesh to_cgal(const DenseMesh& mesh, std::vector<std::size_t>* source = nullptr) {
  std::vector<Point> points;
  points.reserve(mesh.vertices.size());
  for (const auto& v : mesh.vertices) points.emplace_back(v.x(), v.y(), v.z());
  std::vector<std::vector<std::size_t>> polygons;
  polygons.reserve(mesh.faces.size());
  for (const auto& f : mesh.faces) {
    if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2]) continue;  // degenerate index triple
    polygons.push_back({static_cast<std::size_t>(f[0]), static_cast<std::size_t>(f[1]),
                        static_cast<std::size_t>(f[2])});
  }
  std::vector<std::size_t> identity(points.size());
  for (std::size_t i = 0; i < identity.size(); ++i) identity[i] = i;
  DuplicateSources visitor;
  visitor.source = source ? source : &identity;
  if (source) *source = identity;
  PMP::orient_polygon_soup(points, polygons, CGAL::parameters::visitor(visitor));
  if (source) source->resize(points.size());
  CgalMesh out;
  PMP::polygon_soup_to_polygon_mesh(points, polygons, out);
  return out;
}

// Vertex attributes carried through the edge collapse: the mean colour (sRGB, 0-255)
// and the mean normal of the input vertices merged into each vertex, weighted by how
// many each side holds, so a coarse vertex shows its patch's average (a box filter
// over the surface) rather than the colour of one input vertex.
struct Attributes {
  CgalMesh::Property_map<CgalMesh::Vertex_index, Eigen::Vector3f> colour, normal;
  CgalMesh::Property_map<CgalMesh::Vertex_index, float> weight;  // input vertices merged into it
  bool colours = false, normals = false;
};

Attributes add_attributes(CgalMesh& m, const DenseMesh& mesh, const std::vector<std::size_t>& source) {
  Attributes a;
  a.colours = !mesh.colours.empty();
  a.normals = !mesh.normals.empty();
  a.colour = m.add_property_map<CgalMesh::Vertex_index, Eigen::Vector3f>("v:strata_colour").first;
  a.normal = m.add_property_map<CgalMesh::Vertex_index, Eigen::Vector3f>("v:strata_normal").first;
  a.weight = m.add_property_map<CgalMesh::Vertex_index, float>("v:strata_weight", 1.0f).first;
  for (auto v : m.vertices()) {
    const std::size_t i = source[v.idx()];
    if (a.colours) a.colour[v] = mesh.colours[i].cast<float>();
    if (a.normals) a.normal[v] = mesh.normals[i];
  }
  return a;
}

// Merges the attributes of an edge's two vertices into the one the collapse keeps.
class AttributeVisitor : public CGAL::Surface_mesh_simplification::Edge_collapse_visitor_base<CgalMesh> {
 public:
  explicit AttributeVisitor(Attributes& a) : a_(&a) {}
  template <typename Profile, typename Placement>
  void OnCollapsing(const Profile& p, const Placement&) {
    const float w0 = a_->weight[p.v0()], w1 = a_->weight[p.v1()];
    weight_ = w0 + w1;
    if (a_->colours) colour_ = (w0 * a_->colour[p.v0()] + w1 * a_->colour[p.v1()]) / weight_;
    if (a_->normals) {
      const Eigen::Vector3f sum = w0 * a_->normal[p.v0()] + w1 * a_->normal[p.v1()];
      normal_ = sum.norm() > 0 ? Eigen::Vector3f(sum.normalized()) : a_->normal[p.v0()];
    }
  }
  template <typename Profile, typename Vertex>
  void OnCollapsed(const Profile&, const Vertex& kept) {
    a_->weight[kept] = weight_;
    if (a_->colours) a_->colour[kept] = colour_;
    if (a_->normals) a_->normal[kept] = normal_;
  }

 private:
  Attributes* a_;
  float weight_ = 0;
  Eigen::Vector3f colour_ = Eigen::Vector3f::Zero(), normal_ = Eigen::Vector3f::Zero();
};

DenseMesh from_cgal(const CgalMesh& m, const Attributes* a = nullptr) {
  DenseMesh out;
  std::vector<int> index(m.number_of_vertices() + m.number_of_removed_vertices(), -1);
  for (auto v : m.vertices()) {
    index[v.idx()] = static_cast<int>(out.vertices.size());
    const Point& p = m.point(v);
    out.vertices.emplace_back(p.x(), p.y(), p.z());
    if (a && a->colours) {
      const Eigen::Vector3f c = a->colour[v].array().round().min(255.0f).max(0.0f).matrix();
      out.colours.push_back(c.cast<std::uint8_t>());
    }
    if (a && a->normals) out.normals.push_back(a->normal[v]);
  }
  for (auto f : m.faces()) {
    std::array<int, 3> tri{};
    int k = 0;
    for (auto v : CGAL::vertices_around_face(m.halfedge(f), m)) {
      if (k < 3) tri[k] = index[v.idx()];
      ++k;
    }
    if (k == 3) out.faces.push_back(tri);
  }
  return out;
}

}  // namespace

DenseMesh simplify_mesh(const DenseMesh& mesh, std::size_t target_faces) {
  STRATA_CHECK(target_faces > 0, "target_faces must be positive");
  if (mesh.faces.size() <= target_faces) return mesh;
  std::vector<std::size_t> source;
  CgalMesh m = to_cgal(mesh, &source);
  Attributes attributes = add_attributes(m, mesh, source);
  // Count_stop_predicate counts undirected edges; a triangle mesh has about
  // 1.5 edges per face (Euler), so stop at 1.5 x target_faces edges.
  const std::size_t edge_target = target_faces * 3 / 2;
  CGAL::Surface_mesh_simplification::Count_stop_predicate<CgalMesh> stop(edge_target);
  CGAL::Surface_mesh_simplification::edge_collapse(m, stop,
                                                   CGAL::parameters::visitor(AttributeVisitor(attributes)));
  m.collect_garbage();  // keeps the property maps, compacted with the vertices
  return from_cgal(m, &attributes);
}

double closed_mesh_volume_m3(const DenseMesh& mesh) {
  CgalMesh m = to_cgal(mesh);
  if (m.is_empty() || !CGAL::is_closed(m)) {
    throw ProcessingError("mesh volume: the mesh is not closed (it has border edges)");
  }
  // Signed volume by the divergence theorem; orientation decides the sign.
  return std::abs(CGAL::to_double(PMP::volume(m)));
}

}  // namespace strata
