#pragma once
// strata serve: the field station. One process owns the project and serves the web
// pages and the JSON API (docs/api.md, docs/api.yaml); the API calls the same
// controllers as the command line (src/pipeline). cpp-httplib stays inside this module.
#include "server/routes.hpp"

#include <cstddef>
#include <filesystem>
#include <string>

namespace strata {

struct ServeOptions {
  // Address and port to listen on, "HOST:PORT". Only a loopback address until
  // accounts exist (docs/field_station.md).
  std::string listen = "127.0.0.1:8720";
  bool open_browser = false;  // start the desktop's browser on the site page (xdg-open)
  // Bytes: the largest photo an upload may carry (a 50-megapixel JPEG is about 25 MB,
  // a 16-bit TIFF several times that).
  std::size_t max_upload_bytes = std::size_t(256) << 20;
  // Bytes: the largest JSON request body (a unit, a find, a relation is under 1 kB).
  std::size_t max_json_bytes = std::size_t(1) << 20;
  // Requests served at once; each open progress stream (Server-Sent Events) holds one.
  int threads = 32;
  // The role of every caller until the project has accounts: director (the default, the
  // person at this machine), or less for a screen shown to others (viewer: read only).
  Role role = Role::director;

  void validate() const;  // InputError naming the field
};

// The host and port of `listen`; InputError naming the value when it is not HOST:PORT.
struct ListenAddress {
  std::string host;
  int port = 0;
  bool loopback = false;  // 127.0.0.0/8, ::1 or localhost
};
ListenAddress parse_listen_address(const std::string& listen);

// Serves the project in `dir` until SIGINT or SIGTERM; a running job is asked to stop
// (its transaction rolls back) and waited for. Throws InputError (bad options, a
// non-loopback address without accounts), IoError (the port is taken).
void serve(const std::filesystem::path& dir, const ServeOptions& options);

}  // namespace strata
