#include "importers/scans/scan_targets.hpp"

#include "core/door.hpp"
#include "core/error.hpp"
#include "importers/markers/delimited.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <map>

namespace fs = std::filesystem;

namespace strata {
namespace {

constexpr const char* kStage = "importer.scan_targets";
constexpr const char* kColumns = "name,x,y,z (metres, scanner frame)";

}  // namespace

std::vector<ScanTarget> read_scan_targets(const fs::path& file) {
  std::error_code ec;
  door::input_file(file, fmt::format("{}: targets file", kStage), door::kMaxTextFileBytes);
  const DelimitedFile df = read_delimited(file);
  std::vector<int> at = {0, 1, 2, 3};
  std::size_t first = 0;
  if (!df.lines.empty() && df.lines[0].fields.size() >= 2 && !is_number(df.lines[0].fields[1])) {
    const DelimitedLine& header = df.lines[0];
    at = header_columns(header, {{"name", "target", "marker", "id", "label"},
                                 {"x", "e", "east"},
                                 {"y", "n", "north"},
                                 {"z", "h", "height", "up"}});
    const char* names[] = {"name", "x", "y", "z"};
    for (std::size_t c = 0; c < at.size(); ++c)
      if (at[c] < 0)
        throw InputError(fmt::format("{}: {}:{}: the header has no {} column (expected {})", kStage, file.string(),
                                     header.number, names[c], kColumns));
    first = 1;
  }
  const int needed = 1 + *std::max_element(at.begin(), at.end());
  std::vector<ScanTarget> out;
  std::map<std::string, int> seen;  // name -> line
  for (std::size_t i = first; i < df.lines.size(); ++i) {
    const DelimitedLine& line = df.lines[i];
    const std::string where = fmt::format("{}: {}:{}", kStage, file.string(), line.number);
    if (int(line.fields.size()) < needed)
      throw InputError(fmt::format("{}: expected {}, found {} field{}", where, kColumns, line.fields.size(),
                                   line.fields.size() == 1 ? "" : "s"));
    ScanTarget t;
    t.line = line.number;
    t.name = line.fields[std::size_t(at[0])];
    if (t.name.empty()) throw InputError(fmt::format("{}: the target has no name", where));
    t.scanner = {parse_number(line.fields[std::size_t(at[1])], "x", where),
                 parse_number(line.fields[std::size_t(at[2])], "y", where),
                 parse_number(line.fields[std::size_t(at[3])], "z", where)};
    if (auto [it, inserted] = seen.try_emplace(t.name, line.number); !inserted)
      throw InputError(fmt::format("{}: target '{}' is listed again (first on line {})", where, t.name, it->second));
    out.push_back(std::move(t));
  }
  if (out.empty())
    throw InputError(fmt::format("{}: {}: no targets in the file (expected {})", kStage, file.string(), kColumns));
  return out;
}

}  // namespace strata
