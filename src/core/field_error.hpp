#pragma once
// An InputError that knows which field of a record it is about, so that the field
// station can point the user at the input to correct (`{"error": {"message", "field",
// "value"}}`) while the command line prints the same one line.
#include "core/error.hpp"

#include <string>
#include <utility>

namespace strata {

class FieldError : public InputError {
 public:
  FieldError(std::string field, std::string value, const std::string& message)
      : InputError(message), field_(std::move(field)), value_(std::move(value)) {}
  const std::string& field() const { return field_; }
  const std::string& value() const { return value_; }

 private:
  std::string field_;  // the record's field, as the API names it (e.g. "code", "unit")
  std::string value_;  // the value refused, as given
};

}  // namespace strata
