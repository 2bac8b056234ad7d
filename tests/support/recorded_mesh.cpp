#include "support/recorded_mesh.hpp"
#include "exporters/mesh/mesh_writers.hpp"
#include "project/project.hpp"
#include "project/records.hpp"
#include "support/test_support.hpp"

#include <cstdint>
#include <cstring>

namespace strata::test {

void record_dense_mesh(const std::filesystem::path& site, const std::string& layer, const DenseMesh& mesh) {
  Project p = Project::open(site);
  const LayerRecord l = require_layer(p.db(), layer);
  const SiteInfo info = p.site();
  ExportFrame frame;
  frame.site_origin = info.origin;
  frame.crs = info.crs;
  const std::string rel = "products/" + layer + "/dense/mesh.ply";
  std::filesystem::create_directories((site / rel).parent_path());
  write_ply(site / rel, mesh, frame);
  ProductRecord rec;
  rec.layer_id = l.id;
  rec.kind = "mesh";
  rec.path = rel;
  record_product(p.db(), p.dir(), rec);
}

nlohmann::json glb_json(const std::filesystem::path& glb) {
  const std::string b = read_text(glb);
  std::uint32_t magic = 0, json_len = 0;
  if (b.size() < 20) return nullptr;
  std::memcpy(&magic, b.data(), 4);
  std::memcpy(&json_len, b.data() + 12, 4);
  if (magic != 0x46546C67 || 20 + std::size_t{json_len} > b.size()) return nullptr;
  return nlohmann::json::parse(b.substr(20, json_len));
}

}  // namespace strata::test
