#pragma once
// The API's route table as data: method, path in OpenAPI form and the least role it
// needs. The server registers its handlers from it, and tests/unit/server holds it
// against docs/api.yaml, so the documentation and the server cannot drift apart.
#include <string>
#include <vector>

namespace strata {

// Roles of the site's team, each allowed what the ones before it may do.
enum class Role { viewer, recorder, supervisor, director };
const char* to_string(Role role);
Role parse_role(const std::string& text);  // InputError naming the value

struct RouteInfo {
  std::string method;   // "GET", "POST"
  std::string path;     // OpenAPI form, e.g. "/api/layers/{layer}"
  Role role = Role::viewer;
  std::string summary;  // one line, as the API documentation says it
};

const std::vector<RouteInfo>& api_routes();

// The regular expression httplib matches a path against: each {name} one segment.
std::string route_pattern(const std::string& openapi_path);

}  // namespace strata
