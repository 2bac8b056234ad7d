#pragma once
// A layer's dense mesh recorded in a project as the dense stage records it (a PLY of
// double site CRS coordinates under products/LAYER/dense, a `mesh` product row), so
// that the model and viewer exports can be tested without processing photos; and the
// JSON chunk of a .glb.
#include "geometry/mesh.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>

namespace strata::test {

// `mesh` in the site frame (relative to the project's site origin).
void record_dense_mesh(const std::filesystem::path& site, const std::string& layer, const DenseMesh& mesh);

// The JSON chunk of the .glb at `glb`; null when the file is not a glTF binary.
nlohmann::json glb_json(const std::filesystem::path& glb);

}  // namespace strata::test
