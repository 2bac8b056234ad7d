#include "importers/markers/delimited.hpp"

#include "core/error.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <algorithm>
#include <cctype>
#include <fstream>
#include <optional>

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

// A field that starts (after blanks) with a double quote and whose closing quote is
// followed only by blanks up to the separator or the end: its text, "" read as one
// quote, may hold the separator. Returns the position of the separator after it
// (npos at the end of the line), or nothing when the field is not of that form.
std::optional<std::size_t> quoted_field(const std::string& line, std::size_t start, char sep, std::string& text) {
  std::size_t i = start;
  while (i < line.size() && line[i] != sep && (line[i] == ' ' || line[i] == '\t')) ++i;
  if (i >= line.size() || line[i] != '"') return std::nullopt;
  text.clear();
  for (++i; i < line.size(); ++i) {
    if (line[i] != '"') {
      text += line[i];
    } else if (i + 1 < line.size() && line[i + 1] == '"') {
      text += '"';
      ++i;
    } else {
      break;
    }
  }
  if (i >= line.size()) return std::nullopt;  // no closing quote
  const auto pos = line.find(sep, i + 1);
  const std::string rest = line.substr(i + 1, pos == std::string::npos ? pos : pos - i - 1);
  if (rest.find_first_not_of(" \t") != std::string::npos) return std::nullopt;
  return pos;
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
    std::string quoted;
    if (const auto end = quoted_field(line, start, sep, quoted)) {
      out.push_back(quoted);
      if (*end == std::string::npos) break;
      start = *end + 1;
      continue;
    }
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

bool is_number(const std::string& text) {
  if (text.empty()) return false;
  char* end = nullptr;
  std::strtod(text.c_str(), &end);
  return end != text.c_str() && *end == '\0';
}

std::string lower_case(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return text;
}

std::vector<int> header_columns(const DelimitedLine& header, const std::vector<std::vector<std::string>>& aliases) {
  std::vector<int> columns(aliases.size(), -1);
  for (int i = 0; i < int(header.fields.size()); ++i) {
    const std::string name = lower_case(header.fields[std::size_t(i)]);
    for (std::size_t c = 0; c < aliases.size(); ++c)
      if (columns[c] < 0 && std::find(aliases[c].begin(), aliases[c].end(), name) != aliases[c].end()) columns[c] = i;
  }
  return columns;
}

}  // namespace strata
