#include "core/error.hpp"

namespace strata {

void throw_check_failure(const char* expr, const char* file, int line,
                         const std::string& message) {
  throw InternalError(fmt::format("internal error at {}:{}: check '{}' failed{}{}", file,
                                  line, expr, message.empty() ? "" : ": ", message));
}

}  // namespace strata
