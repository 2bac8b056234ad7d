#include "importers/ply/ply_types.hpp"

#include "importers/scans/scan_formats.hpp"

#include <cstdint>

namespace strata::ply {

std::optional<Type> parse_type(std::string_view t) {
  if (t == "char" || t == "int8") return Type::int8;
  if (t == "uchar" || t == "uint8") return Type::uint8;
  if (t == "short" || t == "int16") return Type::int16;
  if (t == "ushort" || t == "uint16") return Type::uint16;
  if (t == "int" || t == "int32") return Type::int32;
  if (t == "uint" || t == "uint32") return Type::uint32;
  if (t == "float" || t == "float32") return Type::float32;
  if (t == "double" || t == "float64") return Type::float64;
  return std::nullopt;
}

std::size_t size_of(Type t) {
  switch (t) {
    case Type::int8:
    case Type::uint8:
      return 1;
    case Type::int16:
    case Type::uint16:
      return 2;
    case Type::int32:
    case Type::uint32:
    case Type::float32:
      return 4;
    case Type::float64:
      return 8;
  }
  return 0;
}

bool is_float(Type t) { return t == Type::float32 || t == Type::float64; }

double decode(const unsigned char* p, Type t, bool swap) {
  using scan_formats::load;
  switch (t) {
    case Type::int8: return load<std::int8_t>(p, swap);
    case Type::uint8: return load<std::uint8_t>(p, swap);
    case Type::int16: return load<std::int16_t>(p, swap);
    case Type::uint16: return load<std::uint16_t>(p, swap);
    case Type::int32: return load<std::int32_t>(p, swap);
    case Type::uint32: return load<std::uint32_t>(p, swap);
    case Type::float32: return load<float>(p, swap);
    case Type::float64: return load<double>(p, swap);
  }
  return 0;
}

}  // namespace strata::ply
