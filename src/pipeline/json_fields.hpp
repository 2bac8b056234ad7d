#pragma once
// One description per struct of how it maps to JSON, used in both directions: a
// `describe(Io& io, T& value)` function names each field once (`io("key", value.field)`)
// and the Writer and Reader below walk it. So a stage result is written for a user
// and read back from the database by the same key list, and code that uses the
// figures reads struct fields, not strings.
//
// Conventions: a missing key or null leaves the field at its default (records
// written by earlier versions lack newer keys), except a double, which reads null as
// NaN (nlohmann writes NaN and infinity as null). std::optional writes null when
// empty. `io.omit_empty(key, value)` leaves the key out when the value is empty.
#include <nlohmann/json.hpp>

#include <cmath>
#include <concepts>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

namespace strata::json_fields {

struct Writer;
struct Reader;

template <typename T>
concept Described = requires(Writer& w, T& v) { describe(w, v); };

// Enumerations are written as the name `to_string` gives and read back by trying
// each value up to `enum_count(T{})` (declared beside describe()).
template <typename T>
concept NamedEnum = std::is_enum_v<T> && requires(T v) {
  { to_string(v) } -> std::convertible_to<std::string>;
  { enum_count(v) } -> std::convertible_to<int>;
};

template <typename T>
nlohmann::json write(const T& v);
template <typename T>
void read(const nlohmann::json& j, T& v);

struct Writer {
  static constexpr bool reading = false;
  nlohmann::json& out;
  template <typename T>
  void operator()(const char* key, const T& v) {
    out[key] = write(v);
  }
  template <typename T>
  void omit_empty(const char* key, const T& v) {
    if constexpr (requires { v.has_value(); }) {
      if (!v.has_value()) return;
    } else {
      if (v.empty()) return;
    }
    out[key] = write(v);
  }
  // A key whose presence a flag of the struct says (false: null).
  template <typename T>
  void when(const char* key, bool present, const T& v) {
    out[key] = present ? write(v) : nlohmann::json(nullptr);
  }
};

struct Reader {
  static constexpr bool reading = true;
  const nlohmann::json& in;
  template <typename T>
  void operator()(const char* key, T& v) {
    if (!in.is_object()) return;
    const auto it = in.find(key);
    if (it != in.end()) read(*it, v);
  }
  template <typename T>
  void omit_empty(const char* key, T& v) {
    (*this)(key, v);
  }
  template <typename T>
  void when(const char* key, bool& present, T& v) {
    if (!in.is_object()) return;
    const auto it = in.find(key);
    present = it != in.end() && !it->is_null();
    if (present) read(*it, v);
  }
};

template <typename T>
nlohmann::json write(const T& v) {
  if constexpr (Described<T>) {
    nlohmann::json j = nlohmann::json::object();
    Writer w{j};
    describe(w, const_cast<T&>(v));  // the Writer only reads
    return j;
  } else if constexpr (NamedEnum<T>) {
    return std::string(to_string(v));
  } else if constexpr (requires { typename T::value_type; v.has_value(); }) {
    return v ? write(*v) : nlohmann::json(nullptr);
  } else if constexpr (std::is_same_v<T, std::string> || std::is_arithmetic_v<T>) {
    return nlohmann::json(v);
  } else {  // a vector
    nlohmann::json a = nlohmann::json::array();
    for (const auto& e : v) a.push_back(write(e));
    return a;
  }
}

template <typename T>
void read(const nlohmann::json& j, T& v) {
  if constexpr (std::is_floating_point_v<T>) {
    v = j.is_number() ? j.get<T>() : std::numeric_limits<T>::quiet_NaN();
  } else if (j.is_null()) {
    if constexpr (requires { v.reset(); }) v.reset();
  } else if constexpr (Described<T>) {
    Reader r{j};
    describe(r, v);
  } else if constexpr (NamedEnum<T>) {
    if (!j.is_string()) return;
    for (int i = 0; i < enum_count(v); ++i) {
      if (j.get<std::string>() == to_string(static_cast<T>(i))) v = static_cast<T>(i);
    }
  } else if constexpr (requires { typename T::value_type; v.has_value(); }) {
    typename T::value_type inner{};
    read(j, inner);
    v = inner;
  } else if constexpr (std::is_same_v<T, bool>) {
    if (j.is_boolean()) v = j.get<bool>();
  } else if constexpr (std::is_arithmetic_v<T>) {
    if (j.is_number()) v = j.get<T>();
  } else if constexpr (std::is_same_v<T, std::string>) {
    if (j.is_string()) v = j.get<std::string>();
  } else {  // a vector
    v.clear();
    if (!j.is_array()) return;
    for (const auto& e : j) {
      typename T::value_type item{};
      read(e, item);
      v.push_back(std::move(item));
    }
  }
}

}  // namespace strata::json_fields
