#pragma once
// Text for markup that strata writes (HTML reports, SVG, QGIS project XML).
#include <string>
#include <string_view>

namespace strata {

// `text` safe as XML/HTML character data and inside attribute values (either quote).
std::string xml_escape(std::string_view text);

}  // namespace strata
