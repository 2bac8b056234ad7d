#pragma once
// CGAL processing of the dense stage's meshes (geometry/mesh.hpp): simplification
// and volume. Eigen/std only: CGAL stays in simplify.cpp. Their writers are in
// exporters/mesh, their readers in importers/mesh.
#include "geometry/mesh.hpp"

#include <cstddef>

namespace strata {

// Edge-collapse simplification (CGAL Surface_mesh_simplification, Lindstrom-Turk
// placement) to at most target_faces triangles. Vertex colours and normals, when the
// mesh has them, are carried over: each simplified vertex has the mean colour and the
// mean (unit) normal of the input vertices nearest to it (its Voronoi cell). Returns
// the mesh unchanged when already small enough.
DenseMesh simplify_mesh(const DenseMesh& mesh, std::size_t target_faces);
// Volume bounded by a closed triangle mesh, cubic metres (CGAL
// Polygon_mesh_processing::volume). Throws ProcessingError when the mesh is not closed.
double closed_mesh_volume_m3(const DenseMesh& mesh);

}  // namespace strata
