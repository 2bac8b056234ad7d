#pragma once
// ISO 8601 times as strata stores them ("2026-05-14T09:31:02Z", UTC).
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace strata {

// Now, "YYYY-MM-DDTHH:MM:SSZ".
std::string utc_now_iso();

// Seconds since 1970 of "YYYY-MM-DD[THH:MM[:SS]]", a time zone suffix ignored (the
// photos of one layer come from one camera clock); nullopt when it is not a date.
std::optional<std::int64_t> iso_seconds(std::string_view text);

}  // namespace strata
