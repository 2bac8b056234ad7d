#pragma once
// Edits of the stratigraphic record that both front ends make: a unit, a relation, a
// layer. Each checks its values, refuses with a FieldError naming the field and the
// value, and writes in one transaction; the caller holds the project lock.
#include "project/project.hpp"
#include "project/records.hpp"

#include <optional>
#include <string>

namespace strata {

// Codes and names as the door checks them (door::name, core/door.hpp): trimmed, NFC,
// printable, at most 64 characters; FieldError naming `field` otherwise.
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
