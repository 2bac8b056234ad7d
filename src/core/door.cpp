#include "core/door.hpp"

#include "core/error.hpp"
#include "core/field_error.hpp"

#include <fmt/format.h>
#include <unicode/normalizer2.h>
#include <unicode/uchar.h>
#include <unicode/unistr.h>
#include <unicode/ustring.h>
#include <unicode/utf8.h>

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <regex>
#include <system_error>

namespace strata::door {
namespace fs = std::filesystem;
namespace {

std::string quoted(const fs::path& p) { return "'" + p.string() + "'"; }

std::string subject(const fs::path& path, std::string_view what) {
  return what.empty() ? quoted(path) : fmt::format("{} {}", what, quoted(path));
}

// The type of `path` after its links, or a refusal naming a loop, a dangling link or
// a path that does not exist.
fs::file_type resolved_type(const fs::path& path, std::string_view what) {
  if (path.empty()) throw InputError(fmt::format("{} is empty: a path is expected", what.empty() ? "path" : what));
  std::error_code ec;
  const fs::file_status own = fs::symlink_status(path, ec);
  if (ec && ec != std::errc::no_such_file_or_directory) {
    if (ec == std::errc::too_many_symbolic_link_levels)
      throw InputError(fmt::format("{} goes through a loop of symbolic links", subject(path, what)));
    throw IoError(fmt::format("{} cannot be examined: {}", subject(path, what), ec.message()));
  }
  if (own.type() == fs::file_type::not_found) throw InputError(fmt::format("{} does not exist", subject(path, what)));
  const fs::file_status target = fs::status(path, ec);
  if (ec == std::errc::too_many_symbolic_link_levels)
    throw InputError(fmt::format("{} is a loop of symbolic links", subject(path, what)));
  if (target.type() == fs::file_type::not_found) {
    std::error_code link_ec;
    const fs::path to = fs::read_symlink(path, link_ec);
    throw InputError(fmt::format("{} is a symbolic link to {}, which does not exist", subject(path, what),
                                 link_ec ? std::string("nothing") : quoted(to)));
  }
  if (ec) throw IoError(fmt::format("{} cannot be examined: {}", subject(path, what), ec.message()));
  return target.type();
}

const char* not_a_file(fs::file_type t) {
  switch (t) {
    case fs::file_type::directory: return "is a folder";
    case fs::file_type::fifo: return "is a named pipe (FIFO)";
    case fs::file_type::socket: return "is a socket";
    case fs::file_type::block:
    case fs::file_type::character: return "is a device";
    default: return "is not a regular file";
  }
}

}  // namespace

// ---- paths -------------------------------------------------------------------

fs::path input_file(const fs::path& path, std::string_view what) {
  const fs::file_type t = resolved_type(path, what);
  if (t != fs::file_type::regular)
    throw InputError(fmt::format("{} {}{}, not a regular file", subject(path, what), not_a_file(t),
                                 t == fs::file_type::fifo ? " that would keep strata waiting for a writer" : ""));
  return path;
}

fs::path input_file(const fs::path& path, std::string_view what, std::uintmax_t max_bytes) {
  input_file(path, what);
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) throw IoError(fmt::format("{} cannot be read: {}", subject(path, what), ec.message()));
  if (size > max_bytes)
    throw InputError(fmt::format("{} is {:.1f} MB, more than the {:.1f} MB it may be", subject(path, what),
                                 double(size) / 1e6, double(max_bytes) / 1e6));
  return path;
}

fs::path input_folder(const fs::path& path, std::string_view what) {
  const fs::file_type t = resolved_type(path, what);
  if (t != fs::file_type::directory) throw InputError(fmt::format("{} is not a folder", subject(path, what)));
  return path;
}

fs::path output_file(const fs::path& path, std::string_view what, bool parent_may_be_missing) {
  if (path.empty()) throw InputError(fmt::format("{} is empty: a file name is expected", what.empty() ? "output" : what));
  std::error_code ec;
  const fs::file_status own = fs::symlink_status(path, ec);
  if (own.type() != fs::file_type::not_found) {
    const fs::file_type t = resolved_type(path, what);
    if (t != fs::file_type::regular)
      throw InputError(fmt::format("{} {}; strata writes only regular files", subject(path, what), not_a_file(t)));
  }
  fs::path parent = path.parent_path();
  if (parent.empty()) parent = ".";
  // The nearest folder that exists must be a folder reached without a loop.
  fs::path existing = parent;
  while (!existing.empty() && fs::symlink_status(existing, ec).type() == fs::file_type::not_found) {
    if (!parent_may_be_missing)
      throw InputError(fmt::format("{}: the folder {} does not exist", subject(path, what), quoted(parent)));
    existing = existing.parent_path();
  }
  if (!existing.empty() && resolved_type(existing, what) != fs::file_type::directory)
    throw InputError(fmt::format("{}: {} is not a folder", subject(path, what), quoted(existing)));
  return path;
}

fs::path output_folder(const fs::path& path, std::string_view what) {
  if (path.empty()) throw InputError(fmt::format("{} is empty: a folder is expected", what.empty() ? "output" : what));
  std::error_code ec;
  if (fs::symlink_status(path, ec).type() != fs::file_type::not_found) {
    if (resolved_type(path, what) != fs::file_type::directory)
      throw InputError(fmt::format("{} exists and is not a folder", subject(path, what)));
    return path;
  }
  const fs::path parent = path.parent_path();
  if (!parent.empty()) output_folder(parent, what);
  return path;
}

// ---- numbers -----------------------------------------------------------------

double number_in(double value, double lo, double hi, std::string_view what, std::string_view unit) {
  if (!std::isfinite(value) || value < lo || value > hi)
    throw InputError(fmt::format("{} = {} is not within {}..{}{}{}", what, value, lo, hi, unit.empty() ? "" : " ",
                                 unit));
  return value;
}

namespace {

std::uint64_t cgroup_limit() {
  for (const char* file : {"/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"}) {
    std::ifstream in(file);
    std::string text;
    if (in >> text && !text.empty() && std::all_of(text.begin(), text.end(), ::isdigit)) {
      try {
        return std::stoull(text);
      } catch (const std::exception&) {
      }
    }
  }
  return 0;
}

}  // namespace

std::uint64_t memory_budget_bytes() {
  static const std::uint64_t budget = [] {
    if (const char* text = std::getenv("STRATA_MEMORY_BUDGET_MB")) {
      char* end = nullptr;
      const double mb = std::strtod(text, &end);
      if (end != text && mb >= 1 && mb <= 1e9) return std::uint64_t(mb * 1e6);
    }
    const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    std::uint64_t total = pages > 0 && page > 0 ? std::uint64_t(pages) * std::uint64_t(page) : (8ull << 30);
    if (const std::uint64_t limit = cgroup_limit(); limit > 0) total = std::min(total, limit);
    return total / 2;
  }();
  return budget;
}

void fits_in_memory(double bytes, std::string_view what, std::string_view remedy) {
  const double budget = double(memory_budget_bytes());
  if (std::isfinite(bytes) && bytes >= 0 && bytes <= budget) return;
  const std::string need = std::isfinite(bytes) && bytes < 1e18 ? fmt::format("{:.3g} GB", bytes / 1e9) : "more memory than exists";
  throw InputError(fmt::format("{} would need {}, more than the {:.1f} GB this machine allows{}", what, need,
                               budget / 1e9, remedy.empty() ? "" : fmt::format(" ({})", remedy)));
}

// ---- codes and names -----------------------------------------------------------

namespace {

// `value` decoded from UTF-8, or FieldError.
icu::UnicodeString decoded(std::string_view field, std::string_view value) {
  // Longer than any code, name or description (and than ICU's 32-bit lengths allow).
  constexpr std::size_t kMaxTextBytes = 1u << 20;
  if (value.size() > kMaxTextBytes)
    throw FieldError(std::string(field), std::string(value.substr(0, 64)) + "...",
                     fmt::format("{} is {} bytes long, over the {} this field takes", field, value.size(), kMaxTextBytes));
  UErrorCode status = U_ZERO_ERROR;
  int32_t length = 0;
  u_strFromUTF8(nullptr, 0, &length, value.data(), int32_t(value.size()), &status);
  if (status == U_INVALID_CHAR_FOUND)
    throw FieldError(std::string(field), std::string(value), fmt::format("{} is not UTF-8 text", field));
  return icu::UnicodeString::fromUTF8(icu::StringPiece(value.data(), int32_t(value.size())));
}

std::string nfc_utf8(std::string_view field, const icu::UnicodeString& text, std::string_view value) {
  UErrorCode status = U_ZERO_ERROR;
  const icu::Normalizer2* nfc = icu::Normalizer2::getNFCInstance(status);
  if (U_FAILURE(status)) throw IoError("the Unicode normalisation data (ICU) is not available");
  const icu::UnicodeString normal = nfc->normalize(text, status);
  if (U_FAILURE(status))
    throw FieldError(std::string(field), std::string(value), fmt::format("{} cannot be normalised", field));
  std::string out;
  normal.toUTF8String(out);
  return out;
}

// Code points of `s` without the white space at both ends.
icu::UnicodeString trimmed(const icu::UnicodeString& s) {
  int32_t begin = 0, end = s.length();
  while (begin < end && u_isUWhiteSpace(s.char32At(begin))) begin = s.moveIndex32(begin, 1);
  while (end > begin) {
    const int32_t before = s.moveIndex32(end, -1);
    if (!u_isUWhiteSpace(s.char32At(before))) break;
    end = before;
  }
  return icu::UnicodeString(s, begin, end - begin);
}

std::string describe_code_point(UChar32 c) { return fmt::format("U+{:04X}", std::uint32_t(c)); }

}  // namespace

std::string name(std::string_view field, std::string_view value, std::size_t max_chars) {
  const std::string f(field), v(value);
  const icu::UnicodeString text = trimmed(decoded(field, value));
  if (text.isEmpty()) throw FieldError(f, v, fmt::format("{} is empty", field));
  for (int32_t i = 0; i < text.length(); i = text.moveIndex32(i, 1)) {
    const UChar32 c = text.char32At(i);
    const int8_t type = u_charType(c);
    const char* kind = nullptr;
    if (type == U_CONTROL_CHAR) kind = "a control character";
    else if (type == U_FORMAT_CHAR) kind = "an invisible format character";
    else if (type == U_UNASSIGNED || type == U_SURROGATE || type == U_PRIVATE_USE_CHAR) kind = "a character that is not text";
    else if (type == U_LINE_SEPARATOR || type == U_PARAGRAPH_SEPARATOR) kind = "a line break";
    if (kind) throw FieldError(f, v, fmt::format("{} holds {} ({})", field, kind, describe_code_point(c)));
  }
  const std::string out = nfc_utf8(field, text, value);
  const std::size_t chars = std::size_t(icu::UnicodeString::fromUTF8(out).countChar32());
  if (chars > max_chars) {
    std::string head;
    icu::UnicodeString(text, 0, text.moveIndex32(0, 16)).toUTF8String(head);
    throw FieldError(f, v, fmt::format("{} '{}...' is {} characters long, more than {}", field, head, chars, max_chars));
  }
  return out;
}

std::string text(std::string_view field, std::string_view value, std::size_t max_chars) {
  const std::string f(field), v(value);
  const icu::UnicodeString t = decoded(field, value);
  for (int32_t i = 0; i < t.length(); i = t.moveIndex32(i, 1)) {
    const UChar32 c = t.char32At(i);
    if (u_charType(c) == U_CONTROL_CHAR && c != '\t' && c != '\n' && c != '\r')
      throw FieldError(f, v, fmt::format("{} holds a control character ({})", field, describe_code_point(c)));
  }
  const std::string out = nfc_utf8(field, t, value);
  const std::size_t chars = std::size_t(icu::UnicodeString::fromUTF8(out).countChar32());
  if (chars > max_chars)
    throw FieldError(f, v, fmt::format("{} is {} characters long, more than {}", field, chars, max_chars));
  return out;
}

std::string name_at(std::string_view at, std::string_view field, std::string_view value) {
  try {
    return name(field, value);
  } catch (const FieldError& e) {
    throw InputError(fmt::format("{}: {}", at, e.what()));
  }
}

std::string text_at(std::string_view at, std::string_view field, std::string_view value) {
  try {
    return text(field, value);
  } catch (const FieldError& e) {
    throw InputError(fmt::format("{}: {}", at, e.what()));
  }
}

// ---- dates ---------------------------------------------------------------------

std::string date_time(std::string_view field, std::string_view value) {
  const std::string f(field), v(value);
  std::string s(value);
  const auto first = s.find_first_not_of(" \t");
  s = first == std::string::npos ? std::string() : s.substr(first, s.find_last_not_of(" \t") - first + 1);
  static const std::regex form(
      R"((\d{4})-(\d{2})-(\d{2})(?:[T ](\d{2}):(\d{2})(?::(\d{2})(?:\.\d{1,9})?)?(Z|[+-](\d{2}):?(\d{2}))?)?)");
  std::smatch m;
  if (!std::regex_match(s, m, form))
    throw FieldError(f, v, fmt::format("{} '{}' is not an ISO 8601 date (YYYY-MM-DD, or YYYY-MM-DDTHH:MM[:SS][zone])",
                                       field, v));
  const int y = std::stoi(m[1]), mo = std::stoi(m[2]), d = std::stoi(m[3]);
  static const int days[] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  const bool leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
  if (mo < 1 || mo > 12) throw FieldError(f, v, fmt::format("{} '{}': there is no month {}", field, v, mo));
  const int month_days = days[mo - 1] + (mo == 2 && leap ? 1 : 0);
  if (d < 1 || d > month_days)
    throw FieldError(f, v, fmt::format("{} '{}': month {} of {} has no day {}", field, v, mo, y, d));
  if (m[4].matched && (std::stoi(m[4]) > 23 || std::stoi(m[5]) > 59))
    throw FieldError(f, v, fmt::format("{} '{}': {}:{} is not a time of day", field, v, m[4].str(), m[5].str()));
  if (m[6].matched && std::stoi(m[6]) > 60)
    throw FieldError(f, v, fmt::format("{} '{}': {} is not a second", field, v, m[6].str()));
  if (m[8].matched && (std::stoi(m[8]) > 14 || std::stoi(m[9]) > 59))
    throw FieldError(f, v, fmt::format("{} '{}': {} is not a time zone", field, v, m[7].str()));
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm utc{};
  gmtime_r(&now, &utc);
  const int next_year = utc.tm_year + 1900 + 1;
  if (y < 1839 || y > next_year)
    throw FieldError(f, v, fmt::format("{} '{}': the year {} is not between 1839 (the first photographs) and {}", field,
                                       v, y, next_year));
  return s;
}

}  // namespace strata::door
