#pragma once
// PLY scalar types (Turk's format): their names, sizes and decoding, shared by the
// point-cloud reader (importers/scans) and the mesh reader (importers/mesh).
#include <cstddef>
#include <optional>
#include <string_view>

namespace strata::ply {

enum class Type { int8, uint8, int16, uint16, int32, uint32, float32, float64 };

// "char"/"int8", "uchar"/"uint8", ... "double"/"float64"; nullopt for another name.
std::optional<Type> parse_type(std::string_view name);
std::size_t size_of(Type t);  // bytes
bool is_float(Type t);
// The value of type t stored at p, in the other byte order than this machine's when
// `swap` (binary_big_endian on x86).
double decode(const unsigned char* p, Type t, bool swap);

}  // namespace strata::ply
