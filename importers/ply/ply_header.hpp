#pragma once
// The PLY header (Turk's format), read once for every PLY reader: the point-cloud
// reader (importers/scans) and the mesh reader (importers/mesh) each check what the
// header declares against what they can read.
#include "importers/ply/ply_types.hpp"

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <string>
#include <string_view>
#include <vector>

namespace strata::ply {

enum class Format { ascii, binary_little_endian, binary_big_endian };
const char* format_name(Format f);  // as the "format" line spells it

struct Property {
  std::string name;
  Type type = Type::float32;      // of the value, or of a list's items
  bool list = false;
  Type count_type = Type::uint8;  // of a list's length (an integer type)
  std::uint64_t line = 0;         // of its "property" line
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::uint64_t line = 0;  // of its "element" line
  std::vector<Property> properties;
};

struct Header {
  Format format = Format::ascii;
  std::vector<Element> elements;           // in file order, which is the body's order
  std::vector<std::string> comments;       // the text after "comment ", in order
  std::vector<std::string> lines;          // every header line, without its line end
  std::uint64_t line_count = 0;            // header lines, end_header included
  std::uint64_t body_offset = 0;           // bytes: where the body starts

  const Element* find(std::string_view name) const;  // the first element so named
};

// Reads the header from the start of `in` and leaves `in` at the body's first
// byte. A header line that is not PLY's grammar ("ply", "format ENCODING VERSION",
// "comment ...", "obj_info ...", "element NAME COUNT", "property TYPE NAME",
// "property list TYPE TYPE NAME", "end_header") throws InputError
// "<stage>: <file>: line N: what".
Header read_header(std::istream& in, const char* stage, const std::filesystem::path& file);

}  // namespace strata::ply
