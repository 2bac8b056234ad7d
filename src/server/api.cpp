// The API's routes: one table of (method, path, least role, handler). Each handler
// parses and checks its request, calls the same functions as the command line
// (src/pipeline, importers/) and answers JSON. docs/api.yaml describes each one.
#include "core/error.hpp"
#include "core/field_error.hpp"
#include "core/hash.hpp"
#include "core/log.hpp"
#include "importers/finds/find_importer.hpp"
#include "importers/photos/photo_importer.hpp"
#include "pipeline/process_layer.hpp"
#include "pipeline/record_edits.hpp"
#include "pipeline/stage_json.hpp"
#include "project/find_records.hpp"
#include "project/records.hpp"
#include "report/report.hpp"
#include "server/http.hpp"
#include "stratigraphy/graphviz.hpp"
#include "stratigraphy/recorded_matrix.hpp"

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <random>

namespace strata::server {
namespace fs = std::filesystem;
using httplib::Request;
using httplib::Response;
using nlohmann::json;

namespace {

// ---- what the pages read -------------------------------------------------------

json unit_json(const UnitRecord& u, const std::vector<LayerRecord>& layers) {
  json ls = json::array();
  for (const auto& l : layers) {
    if (l.unit == u.code) ls.push_back(l.name);
  }
  return {{"code", u.code}, {"type", u.type}, {"description", u.description}, {"layers", ls}};
}

json layer_json(Project& p, const LayerRecord& l) {
  json j = {{"name", l.name},
            {"unit", l.unit},
            {"photos", list_images(p.db(), l.id).size()},
            {"aligned", load_stage_record(p.db(), l.id, "sparse").has_value()},
            {"dense", load_stage_record(p.db(), l.id, "dense").has_value()},
            {"products", load_stage_record(p.db(), l.id, "products").has_value()}};
  if (l.captured_at) j["captured_at"] = *l.captured_at;
  return j;
}

json find_json(const FindRecord& f) {
  return {{"id", f.id},      {"e", f.position.x()}, {"n", f.position.y()},       {"z", f.position.z()},
          {"unit", f.unit}, {"type", f.type},      {"description", f.description}};
}

// The field report's verdict: ready when no finding is a problem to fix first.
json verdict_json(Project& p, const std::string& layer) {
  ReportSummary summary;
  layer_report_html(p, layer, ReportOptions{}, &summary);
  json findings = json::array();
  int problems = 0;
  for (const auto& v : summary.layers) {
    for (const auto& f : v.findings) {
      problems += f.severity == Severity::problem ? 1 : 0;
      findings.push_back(
          {{"severity", to_string(f.severity)}, {"rule", f.rule}, {"message", f.message}, {"advice", f.advice}});
    }
  }
  return {{"ready", problems == 0}, {"problems", problems}, {"findings", findings}};
}

// ---- handlers ------------------------------------------------------------------

void get_session(Context& c, const Request&, Response& res) {
  reply(res, 200, {{"user", nullptr}, {"role", to_string(c.role)}, {"csrf_token", c.csrf_token}});
}

void get_site(Context& c, const Request&, Response& res) {
  Project p = c.read();
  const SiteInfo s = p.site();
  std::size_t photos = 0;
  for (const auto& l : list_layers(p.db())) photos += list_images(p.db(), l.id).size();
  reply(res, 200,
        {{"name", s.name},
         {"crs", s.crs},
         {"origin", s.origin_set ? json{s.origin.x(), s.origin.y(), s.origin.z()} : json(nullptr)},
         {"units", list_units(p.db()).size()},
         {"layers", list_layers(p.db()).size()},
         {"photos", photos},
         {"markers", list_markers(p.db()).size()},
         {"finds", list_finds(p.db()).size()}});
}

void get_units(Context& c, const Request&, Response& res) {
  Project p = c.read();
  const auto layers = list_layers(p.db());
  json out = json::array();
  for (const auto& u : list_units(p.db())) out.push_back(unit_json(u, layers));
  reply(res, 200, out);
}

void post_unit(Context& c, const Request& req, Response& res) {
  const json body = json_body(req);
  UnitRecord u;
  u.code = body_text(body, "code", true);
  u.type = body_text(body, "type", false, "deposit");
  u.description = body_text(body, "description");
  ProjectWriter w = c.write("add unit " + u.code);
  u = add_unit(w.project, u);
  reply(res, 201, unit_json(u, {}));
}

void get_relations(Context& c, const Request&, Response& res) {
  Project p = c.read();
  json out = json::array();
  for (const auto& r : list_relations(p.db())) out.push_back({{"a", r.unit_a}, {"relation", r.kind}, {"b", r.unit_b}});
  reply(res, 200, out);
}

void post_relation(Context& c, const Request& req, Response& res) {
  const json body = json_body(req);
  const std::string a = body_text(body, "a", true), word = body_text(body, "relation", true), b = body_text(body, "b", true);
  ProjectWriter w = c.write(fmt::format("add relation {} {} {}", a, word, b));
  const RelationAdded r = add_relation(w.project, a, word, b);
  reply(res, r.added ? 201 : 200,
        {{"a", r.relation.unit_a}, {"relation", r.relation.kind}, {"b", r.relation.unit_b}, {"added", r.added}});
}

void get_matrix(Context& c, const Request& req, Response& res) {
  Project p = c.read();
  const HarrisMatrix m = recorded_matrix(p.db());
  const std::string format = req.has_param("format") ? req.get_param_value("format") : "json";
  if (format == "json") {
    res.status = 200;
    res.set_content(m.to_json(), "application/json");
    return;
  }
  if (format != "svg") throw HttpError(400, fmt::format("format '{}' is not json or svg", format), "format", format);
  const auto svg = graphviz_svg(m.to_dot());
  if (!svg) throw HttpError(501, "the Harris matrix drawing needs Graphviz's 'dot' (apt-get install graphviz)");
  res.status = 200;
  res.set_content(*svg, "image/svg+xml");
}

void get_layers(Context& c, const Request&, Response& res) {
  Project p = c.read();
  json out = json::array();
  for (const auto& l : list_layers(p.db())) out.push_back(layer_json(p, l));
  reply(res, 200, out);
}

void post_layer(Context& c, const Request& req, Response& res) {
  const json body = json_body(req);
  LayerRecord l;
  l.name = body_text(body, "name", true);
  l.unit = body_text(body, "unit", true);
  const std::string captured = body_text(body, "captured_at");
  if (!captured.empty()) l.captured_at = captured;
  ProjectWriter w = c.write("add layer " + l.name);
  l = add_layer(w.project, l);
  reply(res, 201, layer_json(w.project, l));
}

void get_layer(Context& c, const Request& req, Response& res) {
  Project p = c.read();
  const LayerRecord l = layer_or_404(p, req.matches[1]);
  json j = layer_json(p, l);
  json photos = json::array();
  for (const auto& im : list_images(p.db(), l.id)) {
    photos.push_back({{"name", im.name}, {"sha256", im.sha256}, {"width", im.width}, {"height", im.height}});
  }
  j["photo_list"] = photos;
  if (const auto q = stored_alignment_quality(p.db(), l.id)) j["quality"] = to_json(*q);
  j["verdict"] = j["aligned"].get<bool>() ? verdict_json(p, l.name) : json(nullptr);
  reply(res, 200, j);
}

// A file name as the upload gives it: a plain name, no folder, nothing hidden.
std::string upload_name(const Request& req) {
  if (!req.has_param("name")) throw HttpError(400, "name is missing: the photo's file name (?name=IMG_0042.JPG)", "name");
  const std::string name = req.get_param_value("name");
  const bool bad_char = std::any_of(name.begin(), name.end(), [](char ch) {
    const auto u = static_cast<unsigned char>(ch);
    return u < 0x20 || u == 0x7f || ch == '/' || ch == '\\';
  });
  if (name.empty() || name.size() > 255 || bad_char || name.front() == '.') {
    throw HttpError(400, fmt::format("name '{}' is not a plain file name", name), "name", name);
  }
  return name;
}

// A folder of its own under cache/uploads/ for one upload, removed when done.
struct UploadFolder {
  fs::path path;
  explicit UploadFolder(const fs::path& project_dir) {
    std::random_device rd;
    path = project_dir / "cache" / "uploads" / fmt::format("{:08x}{:08x}", rd(), rd());
    fs::create_directories(path);
  }
  ~UploadFolder() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

void post_photo(Context& c, const Request& req, Response& res, const httplib::ContentReader& content) {
  const std::string name = upload_name(req);
  const std::string layer = req.matches[1];
  ProjectWriter w = c.write(fmt::format("upload photo {} to layer {}", name, layer));
  layer_or_404(w.project, layer);
  UploadFolder folder(c.dir);
  const fs::path file = folder.path / name;
  {
    std::ofstream out(file, std::ios::binary);
    if (!out) throw IoError(fmt::format("upload: cannot write {}", file.string()));
    std::size_t bytes = 0;
    const bool complete = content([&](const char* data, std::size_t n) {
      bytes += n;
      if (bytes > c.options.max_upload_bytes) return false;
      out.write(data, std::streamsize(n));
      return bool(out);
    });
    if (bytes > c.options.max_upload_bytes) {
      throw HttpError(413, fmt::format("photo '{}' is larger than the upload bound of {} MB", name,
                                       c.options.max_upload_bytes >> 20), "name", name);
    }
    if (!complete || !out) throw HttpError(400, fmt::format("photo '{}': the upload was interrupted", name), "name", name);
    if (bytes == 0) throw HttpError(400, fmt::format("photo '{}' is empty", name), "name", name);
  }
  PhotoImportOptions options;
  options.layer = layer;
  PhotoImportSummary s;
  try {
    s = import_photos(w.project, options, {file});
  } catch (const InputError& e) {  // not an image, truncated, named like another photo of the project
    throw HttpError(400, e.what(), "name", name);
  }
  if (!s.bad.empty()) throw HttpError(400, s.bad.front(), "name", name);
  if (s.imported == 0) {
    reply(res, 200, {{"name", name}, {"already_present", true}, {"message", s.already_present.empty() ? "" : s.already_present.front()}});
    return;
  }
  reply(res, 201, {{"name", name}, {"imported", s.imported}, {"without_exif", !s.without_exif.empty()}});
}

void get_report(Context& c, const Request& req, Response& res) {
  Project p = c.read();
  const LayerRecord l = layer_or_404(p, req.matches[1]);
  const auto product = find_product(p.db(), l.id, "report");
  if (!product) {
    throw HttpError(404, fmt::format("layer '{}' has no field report yet: process it first", l.name), "layer", l.name);
  }
  std::ifstream in(c.dir / product->path, std::ios::binary);
  if (!in) throw HttpError(404, fmt::format("layer '{}': its field report file has gone: process it again", l.name));
  const std::string html((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // The report is self-contained (inline CSS and images); nothing in it may run.
  res.set_header("Content-Security-Policy", "default-src 'none'; img-src data:; style-src 'unsafe-inline'; sandbox");
  res.status = 200;
  res.set_content(html, "text/html; charset=utf-8");
}

void post_process(Context& c, const Request& req, Response& res) {
  const json body = req.body.empty() ? json::object() : json_body(req);
  const std::string until = body_text(body, "until", false, "products");
  try {
    parse_process_until(until);
  } catch (const InputError& e) {
    throw HttpError(400, e.what(), "until", until);
  }
  const std::string layer = req.matches[1];
  if (const auto running = c.jobs.running()) {
    throw HttpError(409, fmt::format("job {} ({} of layer {}) is running: wait for it or cancel it", running->id(),
                                     running->kind(), running->layer()));
  }
  ProjectWriter w = c.write(fmt::format("process --layer {}", layer));
  layer_or_404(w.project, layer);
  start_process_job(c, std::move(w), layer, until);
  reply(res, 202, c.jobs.running() ? c.jobs.running()->describe() : c.jobs.list().front()->describe());
}

std::shared_ptr<Job> job_or_404(Context& c, const std::string& id) {
  auto job = c.jobs.find(id);
  if (!job) throw HttpError(404, fmt::format("job '{}' does not exist (jobs last as long as the server)", id), "job", id);
  return job;
}

void get_jobs(Context& c, const Request&, Response& res) {
  json out = json::array();
  for (const auto& j : c.jobs.list()) out.push_back(j->describe());
  reply(res, 200, out);
}

void get_job(Context& c, const Request& req, Response& res) { reply(res, 200, job_or_404(c, req.matches[1])->describe()); }

void get_job_events(Context& c, const Request& req, Response& res) {
  auto job = job_or_404(c, req.matches[1]);
  long after = 0;
  if (req.has_header("Last-Event-ID")) {
    try {
      after = std::stol(req.get_header_value("Last-Event-ID"));
    } catch (const std::exception&) {
      after = 0;
    }
  }
  res.set_header("Cache-Control", "no-store");
  res.set_chunked_content_provider("text/event-stream", [job, after](std::size_t, httplib::DataSink& sink) mutable {
    std::vector<JobEvent> events;
    const bool more = job->events_after(after, events, std::chrono::seconds(10));
    std::string text;
    for (const auto& e : events) {
      text += fmt::format("id: {}\nevent: {}\ndata: {}\n\n", e.id, e.type, e.data);
      after = e.id;
    }
    if (events.empty()) text = ": still running\n\n";  // keeps proxies and the browser from timing out
    if (!sink.is_writable() || !sink.write(text.data(), text.size())) return false;
    if (!more) sink.done();
    return true;
  });
}

void post_job_cancel(Context& c, const Request& req, Response& res) {
  auto job = job_or_404(c, req.matches[1]);
  if (!c.jobs.cancel(job->id())) {
    throw HttpError(409, fmt::format("job {} is not running ({})", job->id(), to_string(job->state())), "job", job->id());
  }
  reply(res, 202, job->describe());
}

void get_markers(Context& c, const Request&, Response& res) {
  Project p = c.read();
  json out = json::array();
  for (const auto& m : list_markers(p.db())) {
    out.push_back({{"name", m.name},
                   {"e", m.position.x()},
                   {"n", m.position.y()},
                   {"z", m.position.z()},
                   {"sigma_m", {m.sigma.x(), m.sigma.y(), m.sigma.z()}},
                   {"role", m.kind}});
  }
  reply(res, 200, out);
}

void get_finds(Context& c, const Request&, Response& res) {
  Project p = c.read();
  json out = json::array();
  for (const auto& f : list_finds(p.db())) out.push_back(find_json(f));
  reply(res, 200, out);
}

void post_find(Context& c, const Request& req, Response& res) {
  const json body = json_body(req);
  FindRecord f;
  f.id = checked_code("id", body_text(body, "id", true));
  f.unit = body_text(body, "unit", true);
  f.type = body_text(body, "type");
  f.description = body_text(body, "description");
  f.position = {body_number(body, "e"), body_number(body, "n"), body_number(body, "z")};
  f.source = "field station";
  ProjectWriter w = c.write("add find " + f.id);
  if (find_find(w.project.db(), f.id)) throw HttpError(409, fmt::format("find '{}' already exists", f.id), "id", f.id);
  if (!find_unit(w.project.db(), checked_code("unit", f.unit))) {
    throw HttpError(400, fmt::format("unit '{}' does not exist", f.unit), "unit", f.unit);
  }
  add_find(w.project, FindImportOptions{}, f);
  const auto stored = find_find(w.project.db(), f.id);
  reply(res, 201, find_json(stored ? *stored : f));
}

}  // namespace

const std::vector<Route>& routes() {
  using R = Role;
  static const std::vector<Route> table = [] {
    std::vector<Route> t = {
      {{"GET", "/api/session", R::viewer, "the caller's role and the CSRF token its writes carry"}, get_session, {}},
      {{"GET", "/api/site", R::viewer, "the site (name, CRS, origin) and its counts"}, get_site, {}},
      {{"GET", "/api/units", R::viewer, "the units, each with its layers"}, get_units, {}},
      {{"POST", "/api/units", R::recorder, "record a unit"}, post_unit, {}},
      {{"GET", "/api/relations", R::viewer, "the relations"}, get_relations, {}},
      {{"POST", "/api/relations", R::recorder, "record a relation; a cycle is refused naming it"}, post_relation, {}},
      {{"GET", "/api/matrix", R::viewer, "the Harris matrix, JSON or SVG"}, get_matrix, {}},
      {{"GET", "/api/layers", R::viewer, "the layers and their state"}, get_layers, {}},
      {{"POST", "/api/layers", R::recorder, "record a layer"}, post_layer, {}},
      {{"GET", "/api/layers/{layer}", R::viewer, "one layer, its photos, figures and verdict"}, get_layer, {}},
      {{"POST", "/api/layers/{layer}/photos", R::recorder, "upload one photo"}, {}, post_photo},
      {{"GET", "/api/layers/{layer}/report", R::viewer, "the layer's field report"}, get_report, {}},
      {{"POST", "/api/layers/{layer}/process", R::supervisor, "start processing the layer"}, post_process, {}},
      {{"GET", "/api/jobs", R::viewer, "the jobs of this server run"}, get_jobs, {}},
      {{"GET", "/api/jobs/{job}", R::viewer, "one job"}, get_job, {}},
      {{"GET", "/api/jobs/{job}/events", R::viewer, "the job's progress as Server-Sent Events"}, get_job_events, {}},
      {{"POST", "/api/jobs/{job}/cancel", R::supervisor, "ask a running job to stop"}, post_job_cancel, {}},
      {{"GET", "/api/markers", R::viewer, "the surveyed markers"}, get_markers, {}},
      {{"GET", "/api/finds", R::viewer, "the finds"}, get_finds, {}},
      {{"POST", "/api/finds", R::recorder, "record a find"}, post_find, {}},
    };
    for (auto& r : marker_routes()) t.push_back(std::move(r));
    for (auto& r : viewer_routes()) t.push_back(std::move(r));
    for (auto& r : map_routes()) t.push_back(std::move(r));
    return t;
  }();
  return table;
}

std::filesystem::path pending_job_file(const std::filesystem::path& dir) { return dir / "cache" / "server" / "job.json"; }

void start_process_job(Context& ctx, ProjectWriter writer, const std::string& layer, const std::string& until) {
  // Kept until the job ends, however it ends: a server killed meanwhile finds it at
  // its next start and runs the job again, the stages done not recomputed.
  const fs::path pending = pending_job_file(ctx.dir);
  fs::create_directories(pending.parent_path());
  {
    std::ofstream out(pending);
    out << json{{"kind", "process"}, {"layer", layer}, {"until", until}}.dump();
  }
  auto held = std::make_shared<ProjectWriter>(std::move(writer));
  ctx.jobs.start("process", layer, [held, layer, until, pending, &ctx](Job&) {
    ProcessRun run;
    run.until = parse_process_until(until);
    // However the job ends, the pending record goes with it, unless the server itself is
    // stopping (then the next start resumes the job); the project is closed (its WAL
    // checkpointed) and its lock released before the job's end is told, so that a page
    // reading the layer at once finds the database free.
    struct Forget {
      const fs::path& pending;
      const std::atomic<bool>& stopping;
      ~Forget() {
        std::error_code ec;
        if (!stopping) fs::remove(pending, ec);
      }
    } forget{pending, ctx.stopping};
    const std::unique_ptr<ProjectLock> lock = std::move(held->lock);
    Project project = std::move(held->project);
    const auto runs = process_layers(project, {layer}, run);
    const LayerRun& r = runs.front();
    if (r.align) {
      return fmt::format("layer {}: {} / {} photos aligned", layer, r.align->quality.sparse.registered_images,
                         r.align->quality.images_total);
    }
    return fmt::format("layer {} processed", layer);
  });
}

}  // namespace strata::server

namespace strata {

const std::vector<RouteInfo>& api_routes() {
  static const std::vector<RouteInfo> infos = [] {
    std::vector<RouteInfo> v;
    for (const auto& r : server::routes()) v.push_back(r.info);
    return v;
  }();
  return infos;
}

}  // namespace strata
