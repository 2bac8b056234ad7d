#pragma once
// Inside the server module only: cpp-httplib, the request context and the errors the
// API answers with.
#include "project/project.hpp"
#include "project/project_lock.hpp"
#include "project/records.hpp"
#include "server/jobs.hpp"
#include "server/routes.hpp"
#include "server/server.hpp"

#include <httplib.h>
#include <nlohmann/json.hpp>

#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

namespace strata::server {

// A refusal: the status and the body {"error": {"message", "field", "value"}}.
class HttpError : public std::runtime_error {
 public:
  HttpError(int status, const std::string& message, std::string field = {}, std::string value = {})
      : std::runtime_error(message), status_(status), field_(std::move(field)), value_(std::move(value)) {}
  int status() const { return status_; }
  const std::string& field() const { return field_; }
  const std::string& value() const { return value_; }

 private:
  int status_;
  std::string field_, value_;
};

// The body of an error answer.
nlohmann::json error_body(const std::string& message, const std::string& field = {}, const std::string& value = {});

// The project opened for one change, holding its write lock (one writer: the CLI and
// the server's requests and jobs take the same lock).
struct ProjectWriter {
  std::unique_ptr<ProjectLock> lock;
  Project project;
};

// What every handler sees of the server.
struct Context {
  std::filesystem::path dir;  // the project folder
  ServeOptions options;
  Role role = Role::director;  // every caller's role until accounts exist
  std::string csrf_token;      // the token writes carry (X-CSRF-Token)
  std::atomic<bool> stopping{false};  // SIGINT/SIGTERM: the server is shutting down
  JobRunner jobs;                     // last: stopped (its job waited for) before the rest goes

  Project read() const { return Project::open(dir); }
  // Refused 409 naming the holder when another command or job holds the lock.
  ProjectWriter write(const std::string& what);
};

using Handler = std::function<void(Context&, const httplib::Request&, httplib::Response&)>;
using UploadHandler =
    std::function<void(Context&, const httplib::Request&, httplib::Response&, const httplib::ContentReader&)>;

struct Route {
  RouteInfo info;
  Handler handler;               // GET, and POST with a JSON body
  UploadHandler upload;          // POST with a streamed body (photos)
};
// Every route: the record's (api.cpp), the marker workspace's (api_markers.cpp) and the
// 3D page's (api_viewer.cpp) and the map's (api_map.cpp).
const std::vector<Route>& routes();
std::vector<Route> marker_routes();
std::vector<Route> viewer_routes();
std::vector<Route> map_routes();

void reply(httplib::Response& res, int status, const nlohmann::json& body);
// The JSON object of a request body; 400 naming the problem when it is not one.
nlohmann::json json_body(const httplib::Request& req);
// A text field of a body: a string when present; `fallback` when absent and not required;
// 400 naming the field otherwise.
std::string body_text(const nlohmann::json& body, const char* field, bool required = false,
                      const std::string& fallback = "");
// A number field: finite; a number or text holding one (a form's value); 400 naming it.
double body_number(const nlohmann::json& body, const char* field);
// The layer of a path, 404 naming it when there is none.
LayerRecord layer_or_404(Project& project, const std::string& name);

// The project file of a stored job that was running when the server stopped: it is
// started again when the server starts (the stages done are not recomputed).
std::filesystem::path pending_job_file(const std::filesystem::path& dir);
void start_process_job(Context& ctx, ProjectWriter writer, const std::string& layer, const std::string& until);

}  // namespace strata::server
