#include "importers/ply/ply_header.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <charconv>
#include <istream>

namespace strata::ply {
namespace {

// A header longer than this is not a PLY header (a binary file with "ply" in front).
constexpr std::uint64_t kMaxHeaderLines = 100000;

std::vector<std::string_view> words(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < s.size() && s[i] != ' ' && s[i] != '\t') ++i;
    if (i > start) out.push_back(s.substr(start, i - start));
  }
  return out;
}

// The header being read, and the errors naming its file and current line.
class HeaderReader {
 public:
  HeaderReader(const char* stage, const std::filesystem::path& file) : stage_(stage), file_(file) {}

  Header read(std::istream& in);

 private:
  InputError error(const std::string& what) const {
    return InputError(fmt::format("{}: {}: line {}: {}", stage_, file_.string(), h_.line_count, what));
  }
  void format(const std::vector<std::string_view>& w);
  void element(const std::vector<std::string_view>& w);
  void property(const std::vector<std::string_view>& w, const std::string& line);

  const char* stage_;
  const std::filesystem::path& file_;
  Header h_;
  bool have_format_ = false;
};

Header HeaderReader::read(std::istream& in) {
  std::string line;
  while (h_.line_count < kMaxHeaderLines && std::getline(in, line)) {
    ++h_.line_count;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    h_.lines.push_back(line);
    const auto w = words(line);
    if (h_.line_count == 1) {
      if (line != "ply") throw error("not a PLY file: it must start with a line 'ply'");
      continue;
    }
    if (w.empty() || w[0] == "obj_info") continue;
    if (w[0] == "comment") {
      const auto text = line.find_first_not_of(" \t", line.find("comment") + 7);
      h_.comments.push_back(text == std::string::npos ? "" : line.substr(text));
    } else if (w[0] == "end_header") {
      if (!have_format_) throw error("the header has no 'format' line");
      h_.body_offset = std::uint64_t(in.tellg());
      return std::move(h_);
    } else if (w[0] == "format") {
      format(w);
    } else if (w[0] == "element") {
      element(w);
    } else if (w[0] == "property") {
      property(w, line);
    } else {
      throw error(fmt::format("unknown header line '{}'", line));
    }
  }
  throw InputError(fmt::format("{}: {}: the header has no end_header line: not a PLY file, or cut short", stage_,
                               file_.string()));
}

void HeaderReader::format(const std::vector<std::string_view>& w) {
  if (w.size() < 2) throw error("'format' without an encoding");
  if (w[1] == "ascii") h_.format = Format::ascii;
  else if (w[1] == "binary_little_endian") h_.format = Format::binary_little_endian;
  else if (w[1] == "binary_big_endian") h_.format = Format::binary_big_endian;
  else throw error(fmt::format("unknown encoding '{}' (ascii, binary_little_endian or binary_big_endian)", w[1]));
  have_format_ = true;
}

void HeaderReader::element(const std::vector<std::string_view>& w) {
  if (w.size() != 3) throw error("expected 'element NAME COUNT'");
  Element e;
  e.name = std::string(w[1]);
  e.line = h_.line_count;
  const auto [end, ec] = std::from_chars(w[2].data(), w[2].data() + w[2].size(), e.count);
  if (ec != std::errc() || end != w[2].data() + w[2].size()) {
    throw error(fmt::format("element count '{}' is not a number (expected 'element NAME COUNT' with a whole number "
                            "COUNT)", w[2]));
  }
  h_.elements.push_back(std::move(e));
}

void HeaderReader::property(const std::vector<std::string_view>& w, const std::string& line) {
  if (h_.elements.empty()) throw error("a property before any element");
  const bool list = w.size() == 5 && w[1] == "list";
  if (!list && w.size() != 3) throw error("expected 'property TYPE NAME' or 'property list TYPE TYPE NAME'");
  const auto type = parse_type(list ? w[3] : w[1]);
  const auto count_type = list ? parse_type(w[2]) : Type::uint8;
  if (!type || !count_type || is_float(*count_type)) throw error(fmt::format("unknown property type in '{}'", line));
  Property p;
  p.name = std::string(w.back());
  p.type = *type;
  p.list = list;
  p.count_type = *count_type;
  p.line = h_.line_count;
  h_.elements.back().properties.push_back(std::move(p));
}

}  // namespace

const char* format_name(Format f) {
  switch (f) {
    case Format::ascii: return "ascii";
    case Format::binary_little_endian: return "binary_little_endian";
    case Format::binary_big_endian: return "binary_big_endian";
  }
  return "";
}

const Element* Header::find(std::string_view name) const {
  for (const Element& e : elements) {
    if (e.name == name) return &e;
  }
  return nullptr;
}

Header read_header(std::istream& in, const char* stage, const std::filesystem::path& file) {
  return HeaderReader(stage, file).read(in);
}

}  // namespace strata::ply
