#include "stratigraphy/recorded_matrix.hpp"

#include "project/records.hpp"

namespace strata {

HarrisMatrix recorded_matrix(Database& db) {
  std::vector<std::string> codes;
  for (const auto& u : list_units(db)) codes.push_back(u.code);
  std::vector<CanonicalRelation> relations;
  for (const auto& r : list_relations(db)) {
    if (auto kind = relation_kind_from_string(r.kind)) relations.push_back({r.unit_a, *kind, r.unit_b});
  }
  return HarrisMatrix(codes, relations);
}

}  // namespace strata
