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
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Count_stop_predicate.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>
#include <CGAL/boost/graph/helpers.h>

#include <vector>

namespace strata {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using CgalMesh = CGAL::Surface_mesh<Point>;
namespace PMP = CGAL::Polygon_mesh_processing;

// Builds a CGAL surface mesh from the triangle soup; orient_polygon_soup splits
// non-manifold vertices/edges (marching-cubes output may have a few), so that the
// halfedge structure is always valid.
CgalMesh to_cgal(const DenseMesh& mesh) {
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
  PMP::orient_polygon_soup(points, polygons);
  CgalMesh out;
  PMP::polygon_soup_to_polygon_mesh(points, polygons, out);
  return out;
}

DenseMesh from_cgal(const CgalMesh& m) {
  DenseMesh out;
  std::vector<int> index(m.number_of_vertices() + m.number_of_removed_vertices(), -1);
  for (auto v : m.vertices()) {
    index[v.idx()] = static_cast<int>(out.vertices.size());
    const Point& p = m.point(v);
    out.vertices.emplace_back(p.x(), p.y(), p.z());
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
  CgalMesh m = to_cgal(mesh);
  // Count_stop_predicate counts undirected edges; a triangle mesh has about
  // 1.5 edges per face (Euler), so stop at 1.5 x target_faces edges.
  const std::size_t edge_target = target_faces * 3 / 2;
  CGAL::Surface_mesh_simplification::Count_stop_predicate<CgalMesh> stop(edge_target);
  CGAL::Surface_mesh_simplification::edge_collapse(m, stop);
  m.collect_garbage();
  return from_cgal(m);
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
