// CGAL processing of dense meshes: the only translation unit of the module that
// includes CGAL (its headers are heavy; see docs/dependencies).
#include "core/error.hpp"
#include "dense/dense_mesh.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Orthogonal_k_neighbor_search.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Search_traits_3.h>
#include <CGAL/Search_traits_adapter.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>
#include <CGAL/boost/graph/helpers.h>

#include <boost/iterator/counting_iterator.hpp>

#include <cmath>
#include <memory>
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

// Stops the edge collapse once at most `target` faces are left (Surface_mesh counts
// the faces not yet removed in constant time).
struct FaceCountStop {
  const CgalMesh* mesh;
  std::size_t target;
  template <typename F, typename Profile>
  bool operator()(const F&, const Profile&, std::size_t, std::size_t) const {
    return mesh->number_of_faces() <= target;
  }
};

// The nearest of a set of points, by index (CGAL kd-tree).
class NearestPoint {
 public:
  explicit NearestPoint(const std::vector<Eigen::Vector3d>& vertices) {
    points_.reserve(vertices.size());
    for (const auto& v : vertices) points_.emplace_back(v.x(), v.y(), v.z());
    tree_ = std::make_unique<Tree>(boost::counting_iterator<std::size_t>(0),
                                   boost::counting_iterator<std::size_t>(points_.size()), Tree::Splitter(),
                                   Traits(Map(points_.data())));
    tree_->build();
  }
  std::size_t operator()(const Eigen::Vector3d& p) const {
    const Search search(*tree_, Point(p.x(), p.y(), p.z()), 1, 0, true, Distance(Map(points_.data())));
    return search.begin()->first;
  }

 private:
  using Map = CGAL::Pointer_property_map<Point>::const_type;
  using Traits = CGAL::Search_traits_adapter<std::size_t, Map, CGAL::Search_traits_3<Kernel>>;
  using Search = CGAL::Orthogonal_k_neighbor_search<Traits>;
  using Tree = Search::Tree;
  using Distance = Search::Distance;
  std::vector<Point> points_;
  std::unique_ptr<Tree> tree_;
};

// The simplified mesh's colours and normals from the input's: each simplified vertex
// takes the mean colour (sRGB, as stored) and the mean normal of the input vertices
// nearer to it than to any other simplified vertex (its Voronoi cell on the input
// surface), a box filter at the level's own spacing: a coarse vertex shows its patch's
// average instead of one input vertex's colour, and nothing drifts with the order of
// the collapses. A vertex whose cell is empty takes its nearest input vertex's.
void carry_attributes(const DenseMesh& input, DenseMesh& simplified) {
  const bool colours = !input.colours.empty(), normals = !input.normals.empty();
  if ((!colours && !normals) || simplified.vertices.empty()) return;
  const std::size_t n = simplified.vertices.size();
  std::vector<Eigen::Vector3d> colour_sum(n, Eigen::Vector3d::Zero()), normal_sum(n, Eigen::Vector3d::Zero());
  std::vector<std::size_t> count(n, 0);
  const NearestPoint nearest_simplified(simplified.vertices);
  for (std::size_t i = 0; i < input.vertices.size(); ++i) {
    const std::size_t k = nearest_simplified(input.vertices[i]);
    ++count[k];
    if (colours) colour_sum[k] += input.colours[i].cast<double>();
    if (normals) normal_sum[k] += input.normals[i].cast<double>();
  }
  std::unique_ptr<NearestPoint> nearest_input;  // only for empty cells
  if (colours) simplified.colours.resize(n);
  if (normals) simplified.normals.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    if (count[k] == 0) {
      if (!nearest_input) nearest_input = std::make_unique<NearestPoint>(input.vertices);
      const std::size_t i = (*nearest_input)(simplified.vertices[k]);
      if (colours) simplified.colours[k] = input.colours[i];
      if (normals) simplified.normals[k] = input.normals[i];
      continue;
    }
    if (colours) {
      const Eigen::Vector3d c = (colour_sum[k] / double(count[k])).array().round().min(255.0).max(0.0).matrix();
      simplified.colours[k] = c.cast<std::uint8_t>();
    }
    if (normals) {
      simplified.normals[k] = normal_sum[k].norm() > 0 ? Eigen::Vector3f(normal_sum[k].normalized().cast<float>())
                                                       : Eigen::Vector3f::Zero();  // writers take the faces' then
    }
  }
}

}  // namespace

DenseMesh simplify_mesh(const DenseMesh& mesh, std::size_t target_faces) {
  STRATA_CHECK(target_faces > 0, "target_faces must be positive");
  if (mesh.faces.size() <= target_faces) return mesh;
  CgalMesh m = to_cgal(mesh);
  // Stops on the faces left: an edge count (Count_stop_predicate, 1.5 edges per face on
  // a closed mesh) ends well below the target on an open one with many border edges
  // (0.74 x on a fused layer mesh).
  CGAL::Surface_mesh_simplification::edge_collapse(m, FaceCountStop{&m, target_faces});
  m.collect_garbage();
  DenseMesh out = from_cgal(m);
  carry_attributes(mesh, out);
  return out;
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
