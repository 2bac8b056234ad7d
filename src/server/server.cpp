// strata serve: the HTTP server around the API's route table (api.cpp): the checks
// every request passes before its handler (the address it was sent to, its size, its
// CSRF token, the caller's role), the answers to errors, the pages, and the signals.
#include "server/server.hpp"

#include "core/error.hpp"
#include "core/field_error.hpp"
#include "core/log.hpp"
#include "project/records.hpp"
#include "server/http.hpp"

#include <fmt/format.h>

#include <cmath>
#include <csignal>
#include <cstdint>
#include <fstream>
#include <map>
#include <pthread.h>
#include <random>
#include <regex>
#include <thread>

namespace strata {

// The pages (web/), embedded by cmake/embed.cmake.
namespace web {
const std::vector<std::pair<std::string_view, std::string_view>>& files();
}

namespace fs = std::filesystem;
using httplib::Request;
using httplib::Response;
using nlohmann::json;

const char* to_string(Role role) {
  switch (role) {
    case Role::viewer: return "viewer";
    case Role::recorder: return "recorder";
    case Role::supervisor: return "supervisor";
    case Role::director: return "director";
  }
  return "viewer";
}

Role parse_role(const std::string& text) {
  for (Role r : {Role::viewer, Role::recorder, Role::supervisor, Role::director}) {
    if (text == to_string(r)) return r;
  }
  throw FieldError("role", text, fmt::format("role '{}' is not viewer, recorder, supervisor or director", text));
}

std::string route_pattern(const std::string& openapi_path) {
  static const std::regex parameter(R"(\{[a-z_]+\})");
  return std::regex_replace(openapi_path, parameter, "([^/]+)");
}

ListenAddress parse_listen_address(const std::string& listen) {
  static const std::regex form(R"((\[[0-9a-fA-F:]+\]|[A-Za-z0-9.-]+):(\d{1,5}))");
  std::smatch m;
  if (!std::regex_match(listen, m, form) || std::stoi(m[2]) > 65535) {
    throw FieldError("--listen", listen, fmt::format("--listen '{}' is not HOST:PORT, e.g. 127.0.0.1:8720", listen));
  }
  ListenAddress a;
  a.host = m[1];
  if (a.host.front() == '[') a.host = a.host.substr(1, a.host.size() - 2);
  a.port = std::stoi(m[2]);
  a.loopback = a.host == "localhost" || a.host == "::1" || a.host.rfind("127.", 0) == 0;
  return a;
}

void ServeOptions::validate() const {
  parse_listen_address(listen);
  if (max_upload_bytes < (std::size_t(1) << 20)) throw FieldError("--max-upload-mb", "", "--max-upload-mb must be at least 1");
  if (threads < 4 || threads > 1024) {
    throw FieldError("--threads-http", std::to_string(threads), "--http-threads must be within 4..1024");
  }
}

namespace server {
namespace {

const std::regex kApiPrefix("^/api/");

std::string random_token() {
  std::random_device rd;
  std::string t;
  for (int i = 0; i < 8; ++i) t += fmt::format("{:08x}", rd());
  return t;
}

bool is_write(const std::string& method) { return method != "GET" && method != "HEAD" && method != "OPTIONS"; }

// The route of a request, by method and path; nullptr when none.
const Route* match_route(const Request& req) {
  for (const auto& r : routes()) {
    if (r.info.method != req.method) continue;
    static thread_local std::map<std::string, std::regex> compiled;
    auto it = compiled.find(r.info.path);
    if (it == compiled.end()) it = compiled.emplace(r.info.path, std::regex(route_pattern(r.info.path))).first;
    if (std::regex_match(req.path, it->second)) return &r;
  }
  return nullptr;
}

std::string content_type_of(std::string_view name) {
  const auto dot = name.rfind('.');
  const std::string_view ext = dot == std::string_view::npos ? "" : name.substr(dot + 1);
  if (ext == "html") return "text/html; charset=utf-8";
  if (ext == "css") return "text/css; charset=utf-8";
  if (ext == "js") return "application/javascript; charset=utf-8";
  if (ext == "svg") return "image/svg+xml";
  if (ext == "json") return "application/json";
  return "application/octet-stream";
}

// Every check made before a handler runs. Returns Handled with the refusal written.
httplib::Server::HandlerResponse check_request(Context& c, const std::vector<std::string>& hosts, const Request& req,
                                               Response& res) {
  const auto refuse = [&](int status, const std::string& message) {
    reply(res, status, error_body(message));
    return httplib::Server::HandlerResponse::Handled;
  };
  // A page elsewhere that resolves its own name to this address (DNS rebinding) sends
  // its own name as the Host: only this server's names are answered.
  const std::string host = req.get_header_value("Host");
  if (std::find(hosts.begin(), hosts.end(), host) == hosts.end()) {
    return refuse(403, fmt::format("Host '{}' is not this server's address", host));
  }
  if (!std::regex_search(req.path, kApiPrefix)) return httplib::Server::HandlerResponse::Unhandled;
  const Route* route = match_route(req);
  if (!route) return httplib::Server::HandlerResponse::Unhandled;  // 404 from the error handler
  const std::size_t length = req.has_header("Content-Length") ? req.get_header_value<std::uint64_t>("Content-Length") : 0;
  const std::size_t bound = route->upload ? c.options.max_upload_bytes : c.options.max_json_bytes;
  if (length > bound) {
    return refuse(413, fmt::format("the request body of {} bytes is larger than the bound of {} bytes for {} {}", length,
                                   bound, req.method, route->info.path));
  }
  if (is_write(req.method)) {
    const std::string origin = req.get_header_value("Origin");
    if (!origin.empty() && origin != "http://" + host) {
      return refuse(403, fmt::format("a write from the page of another site ({}) is refused", origin));
    }
    if (req.get_header_value("X-CSRF-Token") != c.csrf_token) {
      return refuse(403, "the request has no valid CSRF token (header X-CSRF-Token, from GET /api/session): reload the page");
    }
  }
  if (c.role < route->info.role) {
    return refuse(403, fmt::format("{} {} needs the role {}; this session is a {}", req.method, route->info.path,
                                   to_string(route->info.role), to_string(c.role)));
  }
  return httplib::Server::HandlerResponse::Unhandled;
}

// The answer to an exception a handler threw: what users can cause is a 4xx naming it.
void answer_exception(const Request& req, Response& res, std::exception_ptr ep) {
  try {
    std::rethrow_exception(ep);
  } catch (const HttpError& e) {
    reply(res, e.status(), error_body(e.what(), e.field(), e.value()));
  } catch (const FieldError& e) {
    reply(res, 400, error_body(e.what(), e.field(), e.value()));
  } catch (const InputError& e) {
    reply(res, 400, error_body(e.what()));
  } catch (const CrsError& e) {
    reply(res, 400, error_body(e.what()));
  } catch (const ProcessingError& e) {
    reply(res, 422, error_body(e.what()));
  } catch (const IoError& e) {
    reply(res, 500, error_body(e.what()));
  } catch (const std::exception& e) {
    log::warn("{} {}: internal error: {}", req.method, req.path, e.what());
    reply(res, 500, error_body(fmt::format("internal error: {}", e.what())));
  }
}

void add_security_headers(const Request& req, Response& res) {
  const auto set_default = [&](const char* key, const char* value) {
    if (!res.has_header(key)) res.set_header(key, value);
  };
  set_default("X-Content-Type-Options", "nosniff");
  set_default("Referrer-Policy", "no-referrer");
  set_default("X-Frame-Options", "SAMEORIGIN");
  set_default("Content-Security-Policy",
              "default-src 'self'; img-src 'self' data: blob:; style-src 'self' 'unsafe-inline'; "
              "frame-ancestors 'self'; base-uri 'none'; form-action 'self'");
  if (std::regex_search(req.path, kApiPrefix)) set_default("Cache-Control", "no-store");
}

void register_routes(Context& ctx, httplib::Server& svr) {
  for (const auto& r : routes()) {
    const std::string pattern = route_pattern(r.info.path);
    if (r.upload) {
      svr.Post(pattern, [&ctx, &r](const Request& req, Response& res, const httplib::ContentReader& content) {
        r.upload(ctx, req, res, content);
      });
    } else if (r.info.method == "GET") {
      svr.Get(pattern, [&ctx, &r](const Request& req, Response& res) { r.handler(ctx, req, res); });
    } else {
      svr.Post(pattern, [&ctx, &r](const Request& req, Response& res) { r.handler(ctx, req, res); });
    }
  }
  // The pages, at the site root.
  for (const auto& [name, content] : web::files()) {
    const std::string path = "/" + std::string(name);
    const std::string type = content_type_of(name);
    const std::string_view body = content;
    const auto serve_file = [type, body](const Request&, Response& res) {
      res.set_content(body.data(), body.size(), type);
    };
    svr.Get(std::regex_replace(path, std::regex(R"([.])"), "\\."), serve_file);
    if (name == "index.html") svr.Get("/", serve_file);
  }
  // three.js and Leaflet from Debian (libjs-three, libjs-leaflet); httplib refuses '..'.
  svr.set_file_extension_and_mimetype_mapping("js", "application/javascript; charset=utf-8");
  for (const auto& [mount, folder] : {std::pair{"/lib/three", "/usr/share/javascript/three"},
                                      std::pair{"/lib/leaflet", "/usr/share/javascript/leaflet"}}) {
    if (!svr.set_mount_point(mount, folder)) log::warn("serve: {} not found: the pages that need it will not load", folder);
  }
}

// Started again: a job that was running when the server was last killed.
void resume_pending_job(Context& ctx) {
  const fs::path pending = pending_job_file(ctx.dir);
  if (!fs::exists(pending)) return;
  json j;
  try {
    std::ifstream in(pending);
    j = json::parse(in);
    const std::string layer = j.at("layer"), until = j.at("until");
    log::info("serve: resuming the processing of layer {} that was running when the server stopped", layer);
    ProjectWriter w = ctx.write(fmt::format("process --layer {} (resumed)", layer));
    start_process_job(ctx, std::move(w), layer, until);
  } catch (const std::exception& e) {
    log::warn("serve: the interrupted job in {} could not be resumed: {}", pending.string(), e.what());
    std::error_code ec;
    fs::remove(pending, ec);
  }
}

}  // namespace

json error_body(const std::string& message, const std::string& field, const std::string& value) {
  json e = {{"message", message}};
  if (!field.empty()) e["field"] = field;
  if (!field.empty()) e["value"] = value;
  return {{"error", e}};
}

void reply(Response& res, int status, const json& body) {
  res.status = status;
  res.set_content(body.dump(), "application/json");
}

json json_body(const Request& req) {
  json body;
  try {
    body = json::parse(req.body);
  } catch (const json::exception& e) {
    throw HttpError(400, fmt::format("the request body is not JSON: {}", e.what()), "body");
  }
  if (!body.is_object()) throw HttpError(400, "the request body must be a JSON object", "body");
  return body;
}

// A text field of a JSON body: a string when present; `fallback` when absent and not required.
std::string body_text(const json& body, const char* field, bool required, const std::string& fallback) {
  const auto it = body.find(field);
  if (it == body.end() || it->is_null()) {
    if (required) throw HttpError(400, fmt::format("{} is missing", field), field);
    return fallback;
  }
  if (!it->is_string()) throw HttpError(400, fmt::format("{} must be text, not {}", field, it->dump()), field, it->dump());
  return it->get<std::string>();
}

double body_number(const json& body, const char* field) {
  const auto it = body.find(field);
  if (it == body.end() || it->is_null()) throw HttpError(400, fmt::format("{} is missing", field), field);
  double v = NAN;
  if (it->is_number()) {
    v = it->get<double>();
  } else if (it->is_string()) {
    const std::string s = it->get<std::string>();
    std::size_t used = 0;
    try {
      v = std::stod(s, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != s.size()) throw HttpError(400, fmt::format("{} '{}' is not a number", field, s), field, s);
  }
  if (!std::isfinite(v)) throw HttpError(400, fmt::format("{} must be a finite number", field), field, it->dump());
  return v;
}

LayerRecord layer_or_404(Project& p, const std::string& name) {
  auto l = find_layer(p.db(), name);
  if (!l) throw HttpError(404, fmt::format("layer '{}' does not exist", name), "layer", name);
  return *l;
}

ProjectWriter Context::write(const std::string& what) {
  ProjectLockOptions lock_options;
  lock_options.command = "strata serve: " + what;
  std::unique_ptr<ProjectLock> lock;
  try {
    lock = std::make_unique<ProjectLock>(dir, lock_options);
  } catch (const IoError& e) {
    throw HttpError(409, e.what());
  }
  return {std::move(lock), Project::open(dir)};
}

}  // namespace server

void serve(const fs::path& dir, const ServeOptions& options) {
  options.validate();
  const ListenAddress address = parse_listen_address(options.listen);
  if (!address.loopback) {
    throw FieldError("--listen", options.listen,
                     fmt::format("--listen {}: the field station answers only on the loopback address (127.0.0.1) "
                                 "until the project has accounts: anyone on the network could change the record",
                                 options.listen));
  }
  Project::open(dir);  // refuses a folder that is not a project, and applies migrations once
  server::Context ctx;
  ctx.dir = dir;
  ctx.options = options;
  ctx.role = options.role;
  ctx.csrf_token = server::random_token();
  // Uploads cut off by a killed server: never recorded, removed.
  std::error_code ec;
  fs::remove_all(dir / "cache" / "uploads", ec);

  // SIGINT and SIGTERM go to one waiting thread (blocked everywhere else, before the
  // pool's threads start, so they inherit the mask).
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  // A browser that goes away mid-answer (a closed tab following a job) is a failed
  // write on that connection, not the end of the server.
  std::signal(SIGPIPE, SIG_IGN);

  httplib::Server svr;
  const int threads = options.threads;
  svr.new_task_queue = [threads] { return new httplib::ThreadPool(std::size_t(threads)); };
  svr.set_keep_alive_timeout(1);
  svr.set_payload_max_length(options.max_upload_bytes);
  svr.set_read_timeout(60);
  svr.set_write_timeout(60);
  int port = address.port;
  if (port == 0) {
    port = svr.bind_to_any_port(address.host);
  } else if (!svr.bind_to_port(address.host, port)) {
    port = -1;
  }
  if (port <= 0) throw IoError(fmt::format("serve: cannot listen on {}: the port is taken or the address is not this machine's", options.listen));
  const std::string shown_host = address.host.find(':') != std::string::npos ? "[" + address.host + "]" : address.host;
  const std::vector<std::string> hosts = {fmt::format("{}:{}", shown_host, port), fmt::format("localhost:{}", port),
                                          fmt::format("127.0.0.1:{}", port), fmt::format("[::1]:{}", port)};
  svr.set_pre_routing_handler(
      [&ctx, &hosts](const Request& req, Response& res) { return server::check_request(ctx, hosts, req, res); });
  svr.set_exception_handler(server::answer_exception);
  svr.set_error_handler([](const Request& req, Response& res) {
    if (res.status == 404 && res.body.empty()) {
      server::reply(res, 404, server::error_body(fmt::format("no such page or API route: {} {}", req.method, req.path)));
    } else if (res.status == 413 && res.body.empty()) {
      server::reply(res, 413, server::error_body("the request is larger than the server accepts"));
    }
  });
  svr.set_post_routing_handler(server::add_security_headers);
  server::register_routes(ctx, svr);
  server::resume_pending_job(ctx);

  std::thread stopper([&] {
    int sig = 0;
    sigwait(&signals, &sig);
    log::info("serve: stopping ({}); a running job is asked to stop", sig == SIGINT ? "SIGINT" : "SIGTERM");
    ctx.stopping = true;
    ctx.jobs.stop();
    svr.stop();
  });
  const std::string url = fmt::format("http://{}:{}/", shown_host, port);
  // The one line a script waits for (tests read the port from it).
  fmt::print("strata serve: {} on {} (Ctrl-C stops)\n", dir.string(), url);
  std::fflush(stdout);
  if (options.open_browser) {
    const std::string command = fmt::format("xdg-open '{}' >/dev/null 2>&1 &", url);
    if (std::system(command.c_str()) != 0) log::warn("serve: could not start a browser; open {}", url);
  }
  svr.listen_after_bind();
  if (!ctx.stopping) {  // the listener failed on its own: end the stopper thread too
    ctx.stopping = true;
    pthread_kill(stopper.native_handle(), SIGTERM);
  }
  stopper.join();
  ctx.jobs.stop();
}

}  // namespace strata
