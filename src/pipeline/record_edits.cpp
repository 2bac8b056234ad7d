#include "pipeline/record_edits.hpp"

#include "core/door.hpp"
#include "core/fault.hpp"
#include "core/field_error.hpp"
#include "stratigraphy/harris_matrix.hpp"
#include "stratigraphy/recorded_matrix.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace strata {

std::string checked_code(const std::string& field, const std::string& value) { return door::name(field, value); }

UnitRecord add_unit(Project& p, UnitRecord unit) {
  unit.code = checked_code("code", unit.code);
  unit.description = door::text("description", unit.description);
  const auto& types = unit_types();
  if (std::find(types.begin(), types.end(), unit.type) == types.end()) {
    throw FieldError("type", unit.type,
                     fmt::format("unit type '{}' is not one of {}", unit.type, fmt::join(types, ", ")));
  }
  if (find_unit(p.db(), unit.code)) throw FieldError("code", unit.code, fmt::format("unit '{}' already exists", unit.code));
  Transaction tx(p.db());
  unit.id = insert_unit(p.db(), unit);
  fault::point("stratigraphy.unit_before_commit");
  tx.commit();
  return unit;
}

RelationAdded add_relation(Project& p, const std::string& a, const std::string& word, const std::string& b) {
  const std::string code_a = checked_code("a", a), code_b = checked_code("b", b);
  CanonicalRelation r;
  try {
    r = canonical_relation(code_a, word, code_b);
  } catch (const InputError& e) {
    throw FieldError("relation", word, e.what());
  }
  for (const auto& [field, code] : {std::pair{"a", code_a}, std::pair{"b", code_b}}) {
    if (!find_unit(p.db(), code)) {
      throw FieldError(field, code, fmt::format("unit '{}' does not exist (add it with 'strata unit add')", code));
    }
  }
  HarrisMatrix matrix = recorded_matrix(p.db());
  try {
    matrix.add(r);
  } catch (const InputError& e) {
    throw FieldError("relation", word, e.what());  // the cycle, named
  }
  RelationAdded out;
  out.relation = {0, r.unit_a, to_string(r.kind), r.unit_b};
  Transaction tx(p.db());
  out.relation.id = insert_relation(p.db(), out.relation);
  out.added = out.relation.id != 0;
  fault::point("stratigraphy.relation_before_commit");
  tx.commit();
  return out;
}

LayerRecord add_layer(Project& p, LayerRecord layer) {
  layer.name = checked_code("name", layer.name);
  // A layer's name is the folder of its products (products/<layer>/).
  if (layer.name.find_first_of("/\\") != std::string::npos || layer.name == "." || layer.name == "..") {
    throw FieldError("name", layer.name, fmt::format("layer name '{}' may not hold / or \\, nor be . or ..", layer.name));
  }
  layer.unit = checked_code("unit", layer.unit);
  if (!find_unit(p.db(), layer.unit)) {
    throw FieldError("unit", layer.unit,
                     fmt::format("unit '{}' does not exist (add it with 'strata unit add')", layer.unit));
  }
  if (layer.captured_at) layer.captured_at = door::date_time("captured_at", *layer.captured_at);
  if (find_layer(p.db(), layer.name)) {
    throw FieldError("name", layer.name, fmt::format("layer '{}' already exists", layer.name));
  }
  Transaction tx(p.db());
  layer.id = insert_layer(p.db(), layer);
  fault::point("stratigraphy.layer_before_commit");
  tx.commit();
  return layer;
}

}  // namespace strata
