#pragma once
// Edits of the stratigraphic record that both front ends make: a unit, a relation, a
// layer. Each checks its values, refuses with a FieldError naming the field and the
// value, and writes in one transaction; the caller holds the project lock.
#include "project/project.hpp"
#include "project/records.hpp"

#include <optional>
#include <string>

namespace strata {

// Codes and names: trimmed of surrounding blanks; refused when empty, longer than
// kMaxCodeLength bytes, or holding control characters (they end up in file names, the
// Harris matrix's DOT text and the pages).
inline constexpr std::size_t kMaxCodeLength = 64;
std::string checked_code(const std::string& field, const std::string& value);

// A unit (as `strata unit add`). Returns the record as stored.
UnitRecord add_unit(Project& project, UnitRecord unit);

// 'A word B' (as `strata relation add`): both units must exist, and a relation that
// would make the Harris matrix cyclic is refused naming the cycle.
struct RelationAdded {
  RelationRecord relation;  // in its canonical direction
  bool added = false;       // false: it was already recorded
};
RelationAdded add_relation(Project& project, const std::string& a, const std::string& word, const std::string& b);

// A layer of an existing unit (as `strata layer add`); captured_at, when given, is an
// ISO 8601 date or date and time.
LayerRecord add_layer(Project& project, LayerRecord layer);

}  // namespace strata
