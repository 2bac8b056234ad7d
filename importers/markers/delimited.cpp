#include "importers/markers/delimited.hpp"

#include "core/error.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>

namespace strata {
namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n\xEF\xBB\xBF");
  if (b == std::string::npos) return {};
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

Delimiter detect(const std::string& line) {
  if (line.find(';') != std::string::npos) return Delimiter::semicolon;
  if (line.find(',') != std::string::npos) return Delimiter::comma;
  if (line.find('\t') != std::string::npos) return Delimiter::tab;
  return Delimiter::whitespace;
}

std::vector<std::string> split(const std::string& line, Delimiter d) {
  std::vector<std::string> out;
  if (d == Delimiter::whitespace) {
    std::size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
      if (i >= line.size()) break;
      std::size_t j = i;
      while (j < line.size() && !std::isspace(static_cast<unsigned char>(line[j]))) ++j;
      out.push_back(line.substr(i, j - i));
      i = j;
    }
    return out;
  }
  const char sep = d == Delimiter::comma ? ',' : d == Delimiter::semicolon ? ';' : '\t';
  std::size_t start = 0;
  while (true) {
    const auto pos = line.find(sep, start);
    std::string field = trim(line.substr(start, pos == std::string::npos ? pos : pos - start));
    if (field.size() >= 2 && field.front() == '"' && field.back() == '"') {
      field = field.substr(1, field.size() - 2);
    }
    out.push_back(field);
    if (pos == std::string::npos) break;
    start = pos + 1;
  }
  // A trailing delimiter (common in spreadsheet exports) adds no field.
  while (!out.empty() && out.back().empty()) out.pop_back();
  return out;
}

}  // namespace

DelimitedFile read_delimited(const std::filesystem::path& path, int skip_first,
                             const Delimiter* forced) {
  std::ifstream in(path);
  if (!in) throw IoError(fmt::format("{}: cannot open for reading", path.string()));
  DelimitedFile file;
  bool detected = forced != nullptr;
  if (forced) file.delimiter = *forced;
  std::string raw;
  int number = 0;
  while (std::getline(in, raw)) {
    ++number;
    if (number <= skip_first) {
      file.skipped.push_back(trim(raw));
      continue;
    }
    const std::string line = trim(raw);
    if (line.empty() || line[0] == '#') continue;
    if (!detected) {
      file.delimiter = detect(line);
      detected = true;
    }
    file.lines.push_back({number, split(line, file.delimiter)});
  }
  if (in.bad()) throw IoError(fmt::format("{}: read error", path.string()));
  return file;
}

double parse_number(const std::string& text, const std::string& what, const std::string& where) {
  if (text.empty()) throw InputError(fmt::format("{}: {} is empty", where, what));
  // Accept a decimal comma only when it cannot be a field separator (it isn't one here).
  std::string t = text;
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(t.c_str(), &end);
  if (end == t.c_str() || *end != '\0' || errno == ERANGE) {
    throw InputError(fmt::format("{}: {} '{}' is not a number", where, what, text));
  }
  if (!std::isfinite(v)) {
    throw InputError(fmt::format("{}: {} '{}' is not a finite number", where, what, text));
  }
  return v;
}

}  // namespace strata
