// Coded-target naming as `strata process` takes it from the command line: a rule
// (--target-rule "GCP{id:03}") and an id=name list (--target-names "3=GCP_A, 7=north
// peg"), text a user types or pastes from a spreadsheet. The input is the rule, a
// newline, then the list. Parsed names must be non-empty and trimmed, ids >= 0, and a
// validated naming must name ids without throwing.
#include "features/targets.hpp"
#include "fuzz/fuzz_support.hpp"
#include "fuzz/targets.hpp"

#include <cctype>
#include <string_view>

namespace strata::fuzz {
namespace {

bool trimmed(const std::string& s) {
  return !s.empty() && !std::isspace(static_cast<unsigned char>(s.front())) &&
         !std::isspace(static_cast<unsigned char>(s.back()));
}

}  // namespace

int target_names(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const std::size_t newline = text.find('\n');
  TargetNaming naming;
  naming.rule = std::string(text.substr(0, newline));
  try {
    if (newline != std::string_view::npos) naming.names = parse_target_names(text.substr(newline + 1));
    naming.validate();
  } catch (const InputError&) {
    return 0;  // the message names the entry or the rule; there is no file
  }
  for (const auto& [id, name] : naming.names) {
    if (id < 0 || !trimmed(name)) throw FuzzFailure("parse_target_names: a negative id or an untrimmed name");
  }
  for (int id : {0, 7, 999999, 2147483647}) target_name(naming, id);
  return 0;
}

}  // namespace strata::fuzz
