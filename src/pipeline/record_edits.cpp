#include "pipeline/record_edits.hpp"

#include "core/fault.hpp"
#include "core/field_error.hpp"
#include "stratigraphy/harris_matrix.hpp"
#include "stratigraphy/recorded_matrix.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <regex>

namespace strata {
namespace {

std::string trimmed(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) return {};
  return s.substr(first, s.find_last_not_of(" \t\r\n") - first + 1);
}

// YYYY-MM-DD, optionally THH:MM[:SS[.fff]] and a zone (Z or +HH:MM), with a real
// calendar date and clock time.
bool iso_date_time(const std::string& s) {
  static const std::regex form(
      R"((\d{4})-(\d{2})-(\d{2})(?:[T ](\d{2}):(\d{2})(?::(\d{2})(?:\.\d+)?)?(?:Z|[+-]\d{2}:?\d{2})?)?)");
  std::smatch m;
  if (!std::regex_match(s, m, form)) return false;
  const int y = std::stoi(m[1]), mo = std::stoi(m[2]), d = std::stoi(m[3]);
  if (mo < 1 || mo > 12 || d < 1) return false;
  static const int days[] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  const bool leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
  if (d > days[mo - 1] + (mo == 2 && leap ? 1 : 0)) return false;
  if (m[4].matched && (std::stoi(m[4]) > 23 || std::stoi(m[5]) > 59)) return false;
  if (m[6].matched && std::stoi(m[6]) > 60) return false;
  return true;
}

}  // namespace

std::string checked_code(const std::string& field, const std::string& value) {
  const std::string code = trimmed(value);
  if (code.empty()) throw FieldError(field, value, fmt::format("{} is empty", field));
  if (code.size() > kMaxCodeLength) {
    throw FieldError(field, value, fmt::format("{} '{}...' is longer than {} characters", field,
                                               code.substr(0, 16), kMaxCodeLength));
  }
  const bool control = std::any_of(code.begin(), code.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u < 0x20 || u == 0x7f;
  });
  if (control) throw FieldError(field, value, fmt::format("{} holds a control character", field));
  return code;
}

UnitRecord add_unit(Project& p, UnitRecord unit) {
  unit.code = checked_code("code", unit.code);
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
  if (layer.captured_at && !iso_date_time(*layer.captured_at)) {
    throw FieldError("captured_at", *layer.captured_at,
                     fmt::format("captured at '{}' is not an ISO 8601 date (YYYY-MM-DD[THH:MM:SS])",
                                 *layer.captured_at));
  }
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
