// docs/api.yaml against the server's route table: every route documented with its
// method and role, every documented path a route. The YAML is read line by line in
// the layout docs/api.yaml keeps (paths at two spaces, methods at four, the role at
// six): a path or method written otherwise is not seen, and the test fails on it.
#include "server/routes.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>

#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>

namespace strata {
namespace {

struct DocumentedRoute {
  std::string role;  // x-strata-role; empty when the operation has none
};

// (METHOD path) -> the documented operation.
std::map<std::string, DocumentedRoute> documented_routes(const std::string& yaml) {
  std::map<std::string, DocumentedRoute> out;
  std::istringstream in(yaml);
  std::string line, path, key;
  bool in_paths = false;
  static const std::regex path_line(R"(^  (/[^:]+):\s*$)"), method_line(R"(^    (get|post|put|patch|delete):\s*$)"),
      role_line(R"(^      x-strata-role:\s*([a-z]+)\s*$)");
  std::smatch m;
  while (std::getline(in, line)) {
    if (line.rfind("paths:", 0) == 0) {
      in_paths = true;
      continue;
    }
    if (!in_paths) continue;
    if (!line.empty() && line[0] != ' ') break;  // the next top-level key
    if (std::regex_match(line, m, path_line)) {
      path = m[1];
      key.clear();
    } else if (std::regex_match(line, m, method_line)) {
      std::string method = m[1];
      for (auto& ch : method) ch = char(std::toupper(static_cast<unsigned char>(ch)));
      key = method + " " + path;
      out[key];
    } else if (!key.empty() && std::regex_match(line, m, role_line)) {
      out[key].role = m[1];
    }
  }
  return out;
}

TEST(ApiSpec, EveryRouteIsDocumentedWithItsRoleAndEveryDocumentedPathIsARoute) {
  const auto documented = documented_routes(test::read_text(test::source_dir() / "docs" / "api.yaml"));
  ASSERT_GE(documented.size(), 10u) << "docs/api.yaml's paths were not read";
  std::set<std::string> served;
  for (const auto& r : api_routes()) {
    const std::string key = r.method + " " + r.path;
    served.insert(key);
    const auto it = documented.find(key);
    ASSERT_NE(it, documented.end()) << key << " is served but not in docs/api.yaml";
    EXPECT_EQ(it->second.role, to_string(r.role)) << key << ": docs/api.yaml's x-strata-role differs from the server's";
  }
  for (const auto& [key, doc] : documented) {
    EXPECT_TRUE(served.count(key)) << key << " is in docs/api.yaml but the server has no such route";
  }
}

TEST(ApiSpec, EveryWriteNeedsMoreThanAViewer) {
  // POSTs that compute from the record and change nothing (a section drawn along a
  // line): a viewer's, though they carry the CSRF token as every POST does.
  const std::set<std::string> reads_only = {"/api/sections"};
  for (const auto& r : api_routes()) {
    if (r.method != "GET" && !reads_only.count(r.path)) {
      EXPECT_GT(r.role, Role::viewer) << r.method << " " << r.path;
    }
  }
}

TEST(ApiSpec, PathParametersMatchOneSegment) {
  const std::regex p(route_pattern("/api/layers/{layer}/photos"));
  EXPECT_TRUE(std::regex_match(std::string("/api/layers/L1/photos"), p));
  EXPECT_FALSE(std::regex_match(std::string("/api/layers/L1/x/photos"), p));
  EXPECT_FALSE(std::regex_match(std::string("/api/layers//photos"), p));
}

}  // namespace
}  // namespace strata
