#pragma once
// A `strata serve` started by a test on a scratch project, and a client of its API
// (cpp-httplib's); raw socket exchanges for what a well-behaved client never sends.
#include "integration/field_project.hpp"

#include <httplib.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace strata::test {

// Seconds to wait for the server's first line (it opens the project first).
inline constexpr double kServeStartTimeout_s = 30;

// A TCP connection to 127.0.0.1:port; throws when refused.
int connect_to(int port);
// Sends `request` as it is and returns what the server answers until it closes, its
// JSON body is complete, or five seconds pass.
std::string raw_exchange(int port, const std::string& request);
// Every byte but letters, digits and -._~ as %XX (a query value or a path segment).
std::string percent_encoded(const std::string& text);

// `strata serve SITE --listen 127.0.0.1:0 ARGS...` in the background, and a client of it.
class Served {
 public:
  Served(const std::filesystem::path& scratch, const std::filesystem::path& site, std::vector<std::string> args = {});

  httplib::Client& client() { return *client_; }
  int port() const { return port_; }
  Background& process() { return process_; }
  const std::string& token() const { return token_; }

  // POST with the session's token. Both throw when no answer came (the test fails
  // with the reason, not a crash).
  httplib::Result post(const std::string& path, const nlohmann::json& body);
  httplib::Result upload(const std::string& layer, const std::string& name, const std::string& bytes);
  // GET, refused (std::runtime_error with the status and body) unless 200.
  nlohmann::json get(const std::string& path);
  // The job's Server-Sent Events, read until its end event (or `until` returns true for
  // the text so far).
  std::string follow(const std::string& job, const std::function<bool(const std::string&)>& until = {});

 private:
  Background process_;
  int port_ = 0;
  std::unique_ptr<httplib::Client> client_;
  std::string token_;
};

}  // namespace strata::test
