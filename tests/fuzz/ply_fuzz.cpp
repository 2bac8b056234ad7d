// reader.ply: a binary PLY such as `strata export mesh` writes, or another program's.
// An accepted mesh must be consistent: every face index names a vertex, colours and
// normals (when present) one per vertex; what reads it next relies on that.
#include "fuzz/fuzz_support.hpp"
#include "fuzz/targets.hpp"
#include "importers/mesh/ply_mesh.hpp"

namespace strata::fuzz {

int ply(const std::uint8_t* data, std::size_t size) {
  constexpr const char* kInputName = "mesh_input.ply";
  const auto file = write_input(kInputName, data, size);
  PlyContents ply;
  if (!accepts([&] { ply = read_ply(file); }, kInputName)) return 0;
  const DenseMesh& m = ply.mesh;
  const std::size_t n = m.vertices.size();
  if ((!m.colours.empty() && m.colours.size() != n) || (!m.normals.empty() && m.normals.size() != n)) {
    throw FuzzFailure("reader.ply: colours or normals not one per vertex");
  }
  for (const auto& face : m.faces) {
    for (int k : face) {
      if (k < 0 || std::size_t(k) >= n) throw FuzzFailure("reader.ply: a face index names no vertex");
    }
  }
  return 0;
}

}  // namespace strata::fuzz
