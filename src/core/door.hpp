#pragma once
// The checks at the door (docs/reliability.md, "Checks at the door"): every path,
// number, code, name and date a user hands strata, by the command line or the field
// station, passes one of these before anything is read, allocated or stored. Each
// refuses with one line naming the value and what it is for; a new command gets the
// checks by calling them (the command line attaches the path checks to every option
// named FILE, DIR or --out, src/cli/common.cpp).
//
// Coordinates and geometries need the site and its CRS: project/site_bounds.hpp and
// importers/vector/outline.hpp build on these.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace strata::door {

// ---- paths -------------------------------------------------------------------
// `what` says what the path is for ("finds CSV", "--surface of layer L1"); the
// message is "<what> '<path>' <reason>". Symbolic links are followed; a loop of links
// and a link to nothing are named as such. Nothing is opened.

// A regular file (after links): not missing, not a folder, a named pipe (reading it
// would wait for a writer forever), a socket or a device. Returns `path`.
std::filesystem::path input_file(const std::filesystem::path& path, std::string_view what);
// The bound on a table or text file a user hands strata (a survey, a finds list, a
// unit register, a calibration): far beyond any real one, well within memory.
inline constexpr std::uintmax_t kMaxTextFileBytes = 256ull << 20;
// As input_file, and at most `max_bytes` long (a bound on what a reader will take in).
std::filesystem::path input_file(const std::filesystem::path& path, std::string_view what, std::uintmax_t max_bytes);
// A folder (after links).
std::filesystem::path input_folder(const std::filesystem::path& path, std::string_view what);
// Where a file will be written: absent or a regular file, in a folder that exists
// (or will be made: `parent_may_be_missing`). A named pipe or a device there would
// make the write wait or go elsewhere.
std::filesystem::path output_file(const std::filesystem::path& path, std::string_view what,
                                  bool parent_may_be_missing = true);
// Where a folder of outputs will be written: absent or a folder.
std::filesystem::path output_folder(const std::filesystem::path& path, std::string_view what);

// ---- numbers -----------------------------------------------------------------

// `value` when finite and within [lo, hi]; else InputError "<what> = <value> is not
// within lo..hi <unit>".
double number_in(double value, double lo, double hi, std::string_view what, std::string_view unit);

// The memory a single computation may ask for: half of what this process may use
// (the machine's RAM, or the cgroup limit a batch scheduler sets when lower), or
// STRATA_MEMORY_BUDGET_MB when set (a shared node's share; the fuzz targets' bound).
std::uint64_t memory_budget_bytes();
// Refuses, before allocating, a computation estimated at `bytes`: InputError
// "<what> would need N GB, more than the M GB this machine allows (<remedy>)".
void fits_in_memory(double bytes, std::string_view what, std::string_view remedy);

// ---- codes and names -----------------------------------------------------------
// Unit codes, layer names, find and marker ids: they end up in file names, the
// Harris matrix's DOT text, the pages and other programs' tables.

inline constexpr std::size_t kMaxNameChars = 64;
// Trimmed of surrounding white space; refused (FieldError naming `field` and the
// value) when empty, not UTF-8, holding a control, format or unassigned character or
// a line separator, or longer than `max_chars` characters; returned in Unicode NFC,
// so that one code typed on two keyboards is one code.
std::string name(std::string_view field, std::string_view value, std::size_t max_chars = kMaxNameChars);
// Free text (descriptions): UTF-8, no control characters other than tab and line
// breaks, at most `max_chars` characters, NFC; may be empty.
std::string text(std::string_view field, std::string_view value, std::size_t max_chars = 4000);

// As name() and text(), the refusal (InputError) prefixed with where the value was
// read, e.g. "importer.finds.csv: finds.csv:12".
std::string name_at(std::string_view at, std::string_view field, std::string_view value);
std::string text_at(std::string_view at, std::string_view field, std::string_view value);

// ---- dates ---------------------------------------------------------------------

// An ISO 8601 date or date and time: YYYY-MM-DD, optionally [T ]HH:MM[:SS[.fff]] and a
// zone (Z, +HH:MM, +HHMM). The date must exist in the calendar (no month 13, no
// 30 February), the time on a clock (leap second 60 allowed), the year from 1839 (the
// first photographs) to next year. Time zone rule: a time without a zone is the site's
// local time, as camera clocks keep it, and is stored as given. Returns the value
// trimmed; FieldError otherwise.
std::string date_time(std::string_view field, std::string_view value);

}  // namespace strata::door
