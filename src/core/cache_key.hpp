#pragma once
// Cache keys: a SHA-256 over everything a stored result was computed from. Options
// structs are added whole, field by field (core/reflect.hpp), so a new option enters
// every key that holds its struct without anyone editing the key. A field that
// changes how a stage runs but not what it computes (threads, cache reuse, forcing
// a rerun) is declared Unkeyed and left out.
//
// What can be added: numbers, bools, enums, strings, paths, std::optional,
// std::vector / std::map of addable values, Eigen matrices (anything with data()
// and size() over numbers), and aggregates of these. Anything else (a
// std::function, a class with private state) does not compile: decide what of it
// the result depends on and add that.
#include "core/hash.hpp"
#include "core/reflect.hpp"

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace strata {

// A setting that changes how a stage runs, not what it computes: cache keys skip it.
template <class T>
class Unkeyed {
 public:
  Unkeyed(T value = T{}) : value_(value) {}  // NOLINT(google-explicit-constructor): a drop-in for T
  Unkeyed& operator=(T value) {
    value_ = value;
    return *this;
  }
  operator T() const { return value_; }  // NOLINT(google-explicit-constructor)

 private:
  T value_;
};

namespace cache_key_detail {
template <class T> inline constexpr bool is_unkeyed = false;
template <class T> inline constexpr bool is_unkeyed<Unkeyed<T>> = true;
template <class T> inline constexpr bool is_optional = false;
template <class T> inline constexpr bool is_optional<std::optional<T>> = true;
template <class T> inline constexpr bool is_vector = false;
template <class T, class A> inline constexpr bool is_vector<std::vector<T, A>> = true;
template <class T> inline constexpr bool is_map = false;
template <class K, class V, class C, class A> inline constexpr bool is_map<std::map<K, V, C, A>> = true;
template <class T>
concept ContiguousNumbers = requires(const T& v) {
  v.data();
  v.size();
} && std::is_arithmetic_v<std::remove_cvref_t<decltype(*std::declval<const T&>().data())>>;
}  // namespace cache_key_detail

class CacheKey {
 public:
  // `what` names the result and its format version ("dense v3"): a changed
  // algorithm bumps the version and every stored result of the old one is stale.
  explicit CacheKey(std::string_view what) { add(what); }

  template <class T>
  CacheKey& add(const T& value) {
    put(value);
    return *this;
  }

  std::string hex() { return sha_.hex_digest(); }
  // The first 8 bytes of the digest, for file headers that hold a 64-bit key.
  std::uint64_t u64() {
    const auto d = sha_.digest();
    std::uint64_t k = 0;
    for (int i = 0; i < 8; ++i) k = (k << 8) | d[static_cast<std::size_t>(i)];
    return k;
  }

 private:
  // Each value is written as a type tag and a fixed-size or length-prefixed body,
  // so that no two different sequences of values give the same bytes.
  void raw(char tag, const void* data, std::size_t size) {
    sha_.update(&tag, 1);
    sha_.update(data, size);
  }
  void number(char tag, std::int64_t v) { raw(tag, &v, sizeof v); }
  void length(std::size_t n) { number('#', static_cast<std::int64_t>(n)); }

  template <class T>
  void put(const T& v) {
    using U = std::remove_cvref_t<T>;
    using namespace cache_key_detail;
    if constexpr (is_unkeyed<U>) {
      // how a stage runs, not what it computes
    } else if constexpr (std::is_same_v<U, bool>) {
      number('b', v ? 1 : 0);
    } else if constexpr (std::is_enum_v<U>) {
      number('e', static_cast<std::int64_t>(v));
    } else if constexpr (std::is_integral_v<U>) {
      number('i', static_cast<std::int64_t>(v));
    } else if constexpr (std::is_floating_point_v<U>) {
      const double d = static_cast<double>(v);
      raw('d', &d, sizeof d);
    } else if constexpr (std::is_convertible_v<const U&, std::string_view>) {
      const std::string_view s(v);
      length(s.size());
      raw('s', s.data(), s.size());
    } else if constexpr (std::is_same_v<U, std::filesystem::path>) {
      put(v.generic_string());
    } else if constexpr (is_optional<U>) {
      number('o', v.has_value() ? 1 : 0);
      if (v) put(*v);
    } else if constexpr (is_map<U>) {
      length(v.size());
      for (const auto& [k, x] : v) {
        put(k);
        put(x);
      }
    } else if constexpr (ContiguousNumbers<U>) {
      // contiguous numbers: std::vector<double>, Eigen vectors and matrices
      length(static_cast<std::size_t>(v.size()));
      for (decltype(v.size()) i = 0; i < v.size(); ++i) put(v.data()[i]);
    } else if constexpr (is_vector<U>) {
      length(v.size());
      for (const auto& x : v) put(x);
    } else if constexpr (reflect::Aggregate<U>) {
      length(reflect::field_count<U>);
      reflect::for_each_field(v, [this](const auto& field) { put(field); });
    } else {
      static_assert(sizeof(U) == 0, "CacheKey: this type cannot be added; add what the result depends on");
    }
  }

  Sha256 sha_;
};

}  // namespace strata
