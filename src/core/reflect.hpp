#pragma once
// The fields of an aggregate (a struct of public members without bases or
// constructors), visited in declaration order without naming them. Code that must
// cover every field of an options struct (its cache key) is then derived from the
// struct: a field added later cannot be forgotten.
//
// The field count is the largest N for which T{x1, ..., xN} compiles, each x
// converting to any type; structured bindings of that many names then reach the
// fields. A struct the count gets wrong fails to compile at the binding.
#include <cstddef>
#include <type_traits>
#include <utility>

namespace strata::reflect {

namespace detail {

struct AnyField {
  template <class T>
  operator T&() const noexcept;  // never defined: used in unevaluated contexts only
};

template <class T, std::size_t... I>
constexpr bool brace_constructible(std::index_sequence<I...>) {
  return requires { T{(void(I), AnyField{})...}; };
}

template <class T, std::size_t N = 0>
constexpr std::size_t count_fields() {
  if constexpr (brace_constructible<T>(std::make_index_sequence<N + 1>{})) {
    return count_fields<T, N + 1>();
  } else {
    return N;
  }
}

}  // namespace detail

template <class T>
concept Aggregate = std::is_aggregate_v<T> && std::is_class_v<T> && !std::is_polymorphic_v<T>;

template <Aggregate T>
inline constexpr std::size_t field_count = detail::count_fields<T>();

#define STRATA_REFLECT_NAMES_1 f1
#define STRATA_REFLECT_NAMES_2 STRATA_REFLECT_NAMES_1, f2
#define STRATA_REFLECT_NAMES_3 STRATA_REFLECT_NAMES_2, f3
#define STRATA_REFLECT_NAMES_4 STRATA_REFLECT_NAMES_3, f4
#define STRATA_REFLECT_NAMES_5 STRATA_REFLECT_NAMES_4, f5
#define STRATA_REFLECT_NAMES_6 STRATA_REFLECT_NAMES_5, f6
#define STRATA_REFLECT_NAMES_7 STRATA_REFLECT_NAMES_6, f7
#define STRATA_REFLECT_NAMES_8 STRATA_REFLECT_NAMES_7, f8
#define STRATA_REFLECT_NAMES_9 STRATA_REFLECT_NAMES_8, f9
#define STRATA_REFLECT_NAMES_10 STRATA_REFLECT_NAMES_9, f10
#define STRATA_REFLECT_NAMES_11 STRATA_REFLECT_NAMES_10, f11
#define STRATA_REFLECT_NAMES_12 STRATA_REFLECT_NAMES_11, f12
#define STRATA_REFLECT_NAMES_13 STRATA_REFLECT_NAMES_12, f13
#define STRATA_REFLECT_NAMES_14 STRATA_REFLECT_NAMES_13, f14
#define STRATA_REFLECT_NAMES_15 STRATA_REFLECT_NAMES_14, f15
#define STRATA_REFLECT_NAMES_16 STRATA_REFLECT_NAMES_15, f16
#define STRATA_REFLECT_NAMES_17 STRATA_REFLECT_NAMES_16, f17
#define STRATA_REFLECT_NAMES_18 STRATA_REFLECT_NAMES_17, f18
#define STRATA_REFLECT_NAMES_19 STRATA_REFLECT_NAMES_18, f19
#define STRATA_REFLECT_NAMES_20 STRATA_REFLECT_NAMES_19, f20
#define STRATA_REFLECT_NAMES_21 STRATA_REFLECT_NAMES_20, f21
#define STRATA_REFLECT_NAMES_22 STRATA_REFLECT_NAMES_21, f22
#define STRATA_REFLECT_NAMES_23 STRATA_REFLECT_NAMES_22, f23
#define STRATA_REFLECT_NAMES_24 STRATA_REFLECT_NAMES_23, f24
#define STRATA_REFLECT_NAMES_25 STRATA_REFLECT_NAMES_24, f25
#define STRATA_REFLECT_NAMES_26 STRATA_REFLECT_NAMES_25, f26
#define STRATA_REFLECT_NAMES_27 STRATA_REFLECT_NAMES_26, f27
#define STRATA_REFLECT_NAMES_28 STRATA_REFLECT_NAMES_27, f28
#define STRATA_REFLECT_NAMES_29 STRATA_REFLECT_NAMES_28, f29
#define STRATA_REFLECT_NAMES_30 STRATA_REFLECT_NAMES_29, f30
#define STRATA_REFLECT_NAMES_31 STRATA_REFLECT_NAMES_30, f31
#define STRATA_REFLECT_NAMES_32 STRATA_REFLECT_NAMES_31, f32
#define STRATA_REFLECT_NAMES_33 STRATA_REFLECT_NAMES_32, f33
#define STRATA_REFLECT_NAMES_34 STRATA_REFLECT_NAMES_33, f34
#define STRATA_REFLECT_NAMES_35 STRATA_REFLECT_NAMES_34, f35
#define STRATA_REFLECT_NAMES_36 STRATA_REFLECT_NAMES_35, f36
#define STRATA_REFLECT_NAMES_37 STRATA_REFLECT_NAMES_36, f37
#define STRATA_REFLECT_NAMES_38 STRATA_REFLECT_NAMES_37, f38
#define STRATA_REFLECT_NAMES_39 STRATA_REFLECT_NAMES_38, f39
#define STRATA_REFLECT_NAMES_40 STRATA_REFLECT_NAMES_39, f40
#define STRATA_REFLECT_NAMES_41 STRATA_REFLECT_NAMES_40, f41
#define STRATA_REFLECT_NAMES_42 STRATA_REFLECT_NAMES_41, f42
#define STRATA_REFLECT_NAMES_43 STRATA_REFLECT_NAMES_42, f43
#define STRATA_REFLECT_NAMES_44 STRATA_REFLECT_NAMES_43, f44
#define STRATA_REFLECT_NAMES_45 STRATA_REFLECT_NAMES_44, f45
#define STRATA_REFLECT_NAMES_46 STRATA_REFLECT_NAMES_45, f46
#define STRATA_REFLECT_NAMES_47 STRATA_REFLECT_NAMES_46, f47
#define STRATA_REFLECT_NAMES_48 STRATA_REFLECT_NAMES_47, f48

#define STRATA_REFLECT_CASE(N)                  \
  else if constexpr (n == N) {                  \
    auto& [STRATA_REFLECT_NAMES_##N] = value;   \
    each(STRATA_REFLECT_NAMES_##N);             \
  }

// Calls visit(field) for each field of `value`, in declaration order.
template <class T, class Visit>
  requires Aggregate<std::remove_const_t<T>>
constexpr void for_each_field(T& value, Visit&& visit) {
  constexpr std::size_t n = field_count<std::remove_const_t<T>>;
  auto each = [&](auto&... field) { (visit(field), ...); };
  if constexpr (n == 0) {
  }
  STRATA_REFLECT_CASE(1) STRATA_REFLECT_CASE(2) STRATA_REFLECT_CASE(3) STRATA_REFLECT_CASE(4)
  STRATA_REFLECT_CASE(5) STRATA_REFLECT_CASE(6) STRATA_REFLECT_CASE(7) STRATA_REFLECT_CASE(8)
  STRATA_REFLECT_CASE(9) STRATA_REFLECT_CASE(10) STRATA_REFLECT_CASE(11) STRATA_REFLECT_CASE(12)
  STRATA_REFLECT_CASE(13) STRATA_REFLECT_CASE(14) STRATA_REFLECT_CASE(15) STRATA_REFLECT_CASE(16)
  STRATA_REFLECT_CASE(17) STRATA_REFLECT_CASE(18) STRATA_REFLECT_CASE(19) STRATA_REFLECT_CASE(20)
  STRATA_REFLECT_CASE(21) STRATA_REFLECT_CASE(22) STRATA_REFLECT_CASE(23) STRATA_REFLECT_CASE(24)
  STRATA_REFLECT_CASE(25) STRATA_REFLECT_CASE(26) STRATA_REFLECT_CASE(27) STRATA_REFLECT_CASE(28)
  STRATA_REFLECT_CASE(29) STRATA_REFLECT_CASE(30) STRATA_REFLECT_CASE(31) STRATA_REFLECT_CASE(32)
  STRATA_REFLECT_CASE(33) STRATA_REFLECT_CASE(34) STRATA_REFLECT_CASE(35) STRATA_REFLECT_CASE(36)
  STRATA_REFLECT_CASE(37) STRATA_REFLECT_CASE(38) STRATA_REFLECT_CASE(39) STRATA_REFLECT_CASE(40)
  STRATA_REFLECT_CASE(41) STRATA_REFLECT_CASE(42) STRATA_REFLECT_CASE(43) STRATA_REFLECT_CASE(44)
  STRATA_REFLECT_CASE(45) STRATA_REFLECT_CASE(46) STRATA_REFLECT_CASE(47) STRATA_REFLECT_CASE(48)
  else {
    static_assert(n <= 48, "for_each_field: more than 48 fields; split the struct or add cases");
  }
}

#undef STRATA_REFLECT_CASE

}  // namespace strata::reflect
