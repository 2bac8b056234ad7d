#include "core/time.hpp"

#include <chrono>
#include <cstdio>
#include <ctime>

namespace strata {

std::string utc_now_iso() {
  const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::optional<std::int64_t> iso_seconds(std::string_view text) {
  int y = 0, mo = 0, d = 0, h = 0, mi = 0, se = 0;
  const std::string s(text);
  if (std::sscanf(s.c_str(), "%d-%d-%dT%d:%d:%d", &y, &mo, &d, &h, &mi, &se) < 3) return std::nullopt;
  if (mo < 1 || d < 1 || h < 0 || h > 23 || mi < 0 || mi > 59 || se < 0 || se > 60) return std::nullopt;
  const std::chrono::year_month_day ymd{std::chrono::year(y), std::chrono::month(unsigned(mo)),
                                        std::chrono::day(unsigned(d))};
  if (!ymd.ok()) return std::nullopt;
  return std::int64_t(std::chrono::sys_days(ymd).time_since_epoch().count()) * 86400 + h * 3600 + mi * 60 + se;
}

}  // namespace strata
