#pragma once
// Base64 (RFC 4648, with padding): binary data inlined in HTML (report images, the
// viewer's model).
#include <string>
#include <string_view>

namespace strata {

std::string base64(std::string_view bytes);

}  // namespace strata
