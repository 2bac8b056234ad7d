#pragma once
// Line-oriented delimited text as surveyors export it: comma, semicolon, tab or
// runs of spaces; '#' comments; optional header; a field in double quotes may hold
// the delimiter ("" inside it is a quote). Every parsed value remembers its
// line so errors can name it.
#include <filesystem>
#include <string>
#include <vector>

namespace strata {

struct DelimitedLine {
  int number = 0;                   // 1-based line number in the file
  std::vector<std::string> fields;  // trimmed
};

enum class Delimiter { comma, semicolon, tab, whitespace };

// Reads a file into lines of fields. `skip_first` lines are returned raw in
// `skipped` (e.g. the CRS line of an OpenDroneMap file). Blank and '#' lines are
// dropped. The delimiter is detected from the first data line unless given.
struct DelimitedFile {
  std::vector<DelimitedLine> lines;
  std::vector<std::string> skipped;
  Delimiter delimiter = Delimiter::comma;
};
DelimitedFile read_delimited(const std::filesystem::path& path, int skip_first = 0,
                             const Delimiter* forced = nullptr);

// Parses a finite decimal number; throws InputError "<stage>: file:line: <what>
// '<text>' is not a number" (or "is not finite" for nan/inf).
double parse_number(const std::string& text, const std::string& what, const std::string& where);

// Whether the whole text reads as a decimal number (for telling a header from data).
bool is_number(const std::string& text);
std::string lower_case(std::string text);

// Where each wanted column stands in a header line: aliases[c] lists the names
// (lower case) that column c may have; the result is its index, -1 when absent.
std::vector<int> header_columns(const DelimitedLine& header, const std::vector<std::vector<std::string>>& aliases);

}  // namespace strata
