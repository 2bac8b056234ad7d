// strata serve through its HTTP API, as a browser would use it (docs/field_station.md):
// refusals that name the field and leave the project as it was, the lock of another
// writer, the role of a read-only screen, the loopback rule, and a layer whose photos
// are uploaded and processed through the API, its progress followed as Server-Sent
// Events, giving the same records and products as the command line.
#include "integration/served.hpp"
#include "project/project_lock.hpp"

#include <fmt/format.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <fstream>
#include <regex>
#include <thread>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

namespace strata {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::run_strata;
using test::Served;
using test::raw_exchange;
using test::connect_to;

// The error body's field, "" when it has none.
std::string error_field(const httplib::Result& r) {
  const json j = json::parse(r->body);
  return j.at("error").value("field", "");
}
std::string error_message(const httplib::Result& r) { return json::parse(r->body).at("error").at("message"); }

std::string file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class Serve : public ::testing::Test {
 protected:
  // The server may close a connection before the client has sent all of a refused
  // body (413): a failed write of this process, not its end.
  static inline const bool kIgnoreSigpipe = (std::signal(SIGPIPE, SIG_IGN), true);
  // One synthetic layer of 12 photos processed by the command line to its products,
  // made once for every process of the suite (support/shared_scene.hpp; a scene's name
  // is its executable's own: another executable's scene of the same name is removed).
  static void SetUpTestSuite() {
    scratch_ = new test::ScratchDir("serve");
    try {
      shared_ = test::shared_project("serve_processed", 1, 12, 5, std::vector<std::string>{});
    } catch (const std::exception& e) {
      setup_error_ = e.what();
    }
  }
  void SetUp() override {
    if (!setup_error_.empty()) FAIL() << "the shared project could not be made: " << setup_error_;
  }
  static void TearDownTestSuite() {
    delete scratch_;
    scratch_ = nullptr;
  }
  // Its own folder per test: the server's files are found by name in it.
  static fs::path folder(const std::string& name) {
    const fs::path f = scratch_->path() / name;
    fs::remove_all(f);
    fs::create_directories(f);
    return f;
  }
  static fs::path copy_template(const fs::path& site) {
    test::copy_scene(shared_ / "template", site);
    return site;
  }
  static test::ScratchDir* scratch_;
  static fs::path shared_;
  static std::string setup_error_;
};
test::ScratchDir* Serve::scratch_ = nullptr;
fs::path Serve::shared_;
std::string Serve::setup_error_;

TEST_F(Serve, BadRequestsAreRefusedNamingTheFieldAndTheProjectIsUnchanged) {
  const fs::path dir = folder("refusals"), site = copy_template(dir / "site");
  const test::ProjectState before = test::project_state(site);
  Served s(dir, site);
  auto& c = s.client();

  // No CSRF token, a foreign page's Origin, another Host (DNS rebinding).
  auto r = c.Post("/api/units", json{{"code", "900"}}.dump(), "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 403);
  EXPECT_NE(error_message(r).find("CSRF"), std::string::npos) << r->body;
  r = c.Post("/api/units", {{"X-CSRF-Token", "0123"}}, json{{"code", "900"}}.dump(), "application/json");
  EXPECT_EQ(r->status, 403);
  r = c.Get("/api/site", {{"Host", "evil.example:80"}});
  EXPECT_EQ(r->status, 403);
  EXPECT_NE(error_message(r).find("evil.example"), std::string::npos) << r->body;

  // Values: each refusal names its field.
  struct Case {
    std::string path;
    json body;
    std::string field;
  };
  const std::vector<Case> cases = {
      {"/api/units", json{{"code", "   "}}, "code"},
      {"/api/units", json{{"code", "9\x01"}}, "code"},
      {"/api/units", json{{"code", std::string(65, '9')}}, "code"},
      {"/api/units", json{{"code", 901}}, "code"},
      {"/api/units", json{{"code", "901"}, {"type", "pit"}}, "type"},
      {"/api/units", json{{"code", "101"}}, "code"},  // exists
      {"/api/relations", json{{"a", "101"}, {"relation", "above"}, {"b", "999"}}, "b"},
      {"/api/relations", json{{"a", "101"}, {"relation", "beside"}, {"b", "101"}}, "relation"},
      {"/api/layers", json{{"name", "L9"}, {"unit", "101"}, {"captured_at", "2026-13-45"}}, "captured_at"},
      {"/api/layers", json{{"name", "L9"}, {"unit", "999"}}, "unit"},
      {"/api/layers", json{{"name", ""}, {"unit", "101"}}, "name"},
      {"/api/finds", json{{"id", "F1"}, {"e", "abc"}, {"n", 1}, {"z", 1}, {"unit", "101"}}, "e"},
      {"/api/finds", json{{"id", "F1"}, {"e", 1}, {"n", 1}, {"unit", "101"}}, "z"},
      {"/api/finds", json{{"id", "F1"}, {"e", 1}, {"n", 1}, {"z", 1}, {"unit", "999"}}, "unit"},
      {"/api/layers/L1/process", json{{"until", "everything"}}, "until"},
  };
  for (const auto& k : cases) {
    r = s.post(k.path, k.body);
    ASSERT_TRUE(r) << k.path;
    EXPECT_EQ(r->status / 100, 4) << k.path << " " << k.body.dump() << ": " << r->status;
    EXPECT_EQ(error_field(r), k.field) << k.path << " " << k.body.dump() << ": " << r->body;
  }
  // A cycle in the Harris matrix is refused naming it.
  r = s.post("/api/units", json{{"code", "102"}});
  ASSERT_EQ(r->status, 201) << r->body;
  ASSERT_EQ(s.post("/api/relations", json{{"a", "101"}, {"relation", "above"}, {"b", "102"}})->status, 201);
  r = s.post("/api/relations", json{{"a", "102"}, {"relation", "above"}, {"b", "101"}});
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(error_field(r), "relation");
  EXPECT_NE(error_message(r).find("cycl"), std::string::npos) << r->body;

  // Not JSON; a body over the bound; an unknown route; a photo that is not one, or
  // named to leave its folder.
  r = c.Post("/api/units", {{"X-CSRF-Token", s.get("/api/session").at("csrf_token")}}, "{code", "application/json");
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(error_field(r), "body");
  // A body over the bound is refused from its Content-Length, before it is read: the
  // client sends only the headers and gets its answer.
  const std::string refused = raw_exchange(s.port(), "POST /api/units HTTP/1.1\r\nHost: 127.0.0.1:" +
                                                         std::to_string(s.port()) +
                                                         "\r\nContent-Type: application/json\r\nContent-Length: " +
                                                         std::to_string(2 << 20) + "\r\nX-CSRF-Token: " +
                                                         s.get("/api/session").at("csrf_token").get<std::string>() +
                                                         "\r\n\r\n");
  EXPECT_EQ(refused.rfind("HTTP/1.1 413", 0), 0u) << refused;
  r = s.upload("L1", "huge.jpg", std::string(2 << 20, 'x'));  // within the upload bound: read, then refused
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400);
  r = c.Get("/api/nothing");
  EXPECT_EQ(r->status, 404);
  EXPECT_NO_THROW(error_message(r));
  r = s.upload("L1", "note.jpg", "this is not a photo");
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(error_field(r), "name");
  for (const std::string name : {"../evil.jpg", "a/b.jpg", ".hidden.jpg", ""}) {
    r = s.upload("L1", name, file_bytes(test::layer_photos(shared_ / "data", "L1").front()));
    EXPECT_EQ(r->status, 400) << name;
    EXPECT_EQ(error_field(r), "name") << name;
  }
  r = s.upload("L404", "a.jpg", "x");
  EXPECT_EQ(r->status, 404);
  // Paths out of the served folders.
  for (const std::string path : {"/lib/three/../../../../etc/passwd", "/lib/three/%2e%2e/%2e%2e/%2e%2e/etc/passwd",
                                 "/..%2f..%2fetc/passwd", "/api/layers/..%2f..%2fetc%2fpasswd"}) {
    r = c.Get(path.c_str());
    ASSERT_TRUE(r) << path;
    EXPECT_NE(r->status, 200) << path;
    EXPECT_EQ(r->body.find("root:"), std::string::npos) << path;
  }

  // Only the two units and the relation added on purpose changed the record.
  s.process().kill_now();
  ASSERT_EQ(run_strata({"relation", "list", site.string()}).out, "101 above 102\n");
  const test::ProjectState after = test::project_state(site);
  EXPECT_EQ(after.media, before.media);
}

TEST_F(Serve, RefusedRequestsLeaveEveryRowAsItWas) {
  const fs::path dir = folder("rows"), site = copy_template(dir / "site");
  const test::ProjectState before = test::project_state(site);
  {
    Served s(dir, site);
    EXPECT_EQ(s.post("/api/units", json{{"code", ""}})->status, 400);
    EXPECT_EQ(s.post("/api/layers", json{{"name", "L9"}, {"unit", "101"}, {"captured_at", "2026-02-30"}})->status, 400);
    EXPECT_EQ(s.upload("L1", "x.jpg", std::string(1000, '\xff'))->status, 400);
    EXPECT_EQ(s.post("/api/finds", json{{"id", "F1"}, {"e", 1e308}, {"n", "nan"}, {"z", 1}, {"unit", "101"}})->status, 400);
  }
  EXPECT_EQ(test::project_state(site), before);
  EXPECT_FALSE(fs::exists(site / "cache" / "uploads") && !fs::is_empty(site / "cache" / "uploads"));
}

TEST_F(Serve, RecordsWrittenThroughTheApiAreTheCommandLinesRecords) {
  const fs::path dir = folder("records"), site = copy_template(dir / "site");
  Served s(dir, site);
  const std::string script = "<script>alert(1)</script>";
  auto r = s.post("/api/units", json{{"code", " 102 "}, {"type", "cut"}, {"description", script}});
  ASSERT_EQ(r->status, 201) << r->body;
  EXPECT_EQ(json::parse(r->body).at("code"), "102");  // trimmed
  ASSERT_EQ(s.post("/api/relations", json{{"a", "102"}, {"relation", "below"}, {"b", "101"}})->status, 201);
  r = s.post("/api/layers", json{{"name", "L2"}, {"unit", "102"}, {"captured_at", "2026-06-02T10:15"}});
  ASSERT_EQ(r->status, 201) << r->body;
  r = s.post("/api/finds", json{{"id", "F7"}, {"e", "734000.5"}, {"n", 4174000.25}, {"z", 1450.1}, {"unit", "102"},
                                {"type", "pottery"}});
  ASSERT_EQ(r->status, 201) << r->body;

  const json units = s.get("/api/units");
  ASSERT_EQ(units.size(), 2u);
  EXPECT_EQ(units[1].at("description"), script);
  EXPECT_EQ(units[0].at("layers"), json::array({"L1"}));
  EXPECT_EQ(s.get("/api/relations"), json::parse(R"([{"a":"101","relation":"above","b":"102"}])"));
  const json layers = s.get("/api/layers");
  ASSERT_EQ(layers.size(), 2u);
  EXPECT_EQ(layers[0].at("photos"), 12);
  EXPECT_TRUE(layers[0].at("products").get<bool>());
  EXPECT_EQ(layers[1].at("captured_at"), "2026-06-02T10:15");
  const json finds = s.get("/api/finds");
  ASSERT_EQ(finds.size(), 1u);
  EXPECT_DOUBLE_EQ(finds[0].at("e").get<double>(), 734000.5);
  const json site_json = s.get("/api/site");
  EXPECT_EQ(site_json.at("crs"), "EPSG:32636");
  EXPECT_EQ(site_json.at("finds"), 1);
  const json layer = s.get("/api/layers/L1");
  EXPECT_EQ(layer.at("photo_list").size(), 12u);
  ASSERT_TRUE(layer.at("verdict").is_object());
  EXPECT_TRUE(layer.at("verdict").at("findings").is_array());
  const auto report = s.client().Get("/api/layers/L1/report");
  ASSERT_EQ(report->status, 200);
  EXPECT_NE(report->get_header_value("Content-Security-Policy").find("sandbox"), std::string::npos);
  const auto svg = s.client().Get("/api/matrix?format=svg");
  ASSERT_TRUE(svg);
  if (svg->status == 200) {
    EXPECT_NE(svg->body.find("<svg"), std::string::npos);
  }

  // The command line sees the same record.
  s.process().kill_now();
  const auto list = run_strata({"unit", "list", site.string()});
  EXPECT_NE(list.out.find("102        cut"), std::string::npos) << list.out;
  EXPECT_NE(run_strata({"layer", "list", site.string()}).out.find("L2"), std::string::npos);
  EXPECT_NE(test::database_rows(site / "project.gpkg", {"finds"}).find("F7|102|pottery"), std::string::npos);
}

// The 3D page's model: the viewer page `export viewer` writes, served with a policy that
// lets its own inline scripts run and nothing else load; kept until the record changes.
TEST_F(Serve, TheSiteModelIsServedAsTheViewerPage) {
  const fs::path dir = folder("viewer_page"), site = copy_template(dir / "site");
  Served s(dir, site);
  auto r = s.client().Get("/api/viewer");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body.substr(0, 500);
  const std::string csp = r->get_header_value("Content-Security-Policy");
  EXPECT_NE(csp.find("default-src 'none'"), std::string::npos) << csp;
  EXPECT_NE(csp.find("script-src 'unsafe-inline'"), std::string::npos) << csp;
  EXPECT_NE(r->body.find("<script id=\"model\""), std::string::npos);
  EXPECT_NE(r->body.find("layer L1"), std::string::npos);  // the layer's node, as export viewer names it
  const std::string first = r->body;
  r = s.client().Get("/api/viewer");
  EXPECT_EQ(r->body, first);  // the same record: the same page
  r = s.client().Get("/api/viewer?layer=L404");
  EXPECT_EQ(r->status, 404);
  EXPECT_EQ(error_field(r), "layer");
  // A project with no dense surface: refused with what to do.
  const fs::path bare = dir / "bare";
  ASSERT_EQ(run_strata({"-q", "init", bare.string(), "--crs", "EPSG:32636"}).exit_code, 0);
  Served b(dir, bare);
  r = b.client().Get("/api/viewer");
  EXPECT_EQ(r->status, 400) << r->body.substr(0, 300);
  EXPECT_FALSE(error_message(r).empty());
}

TEST_F(Serve, AWriterMeetingAnotherWritersLockIsToldWhoHoldsIt) {
  const fs::path dir = folder("lock"), site = copy_template(dir / "site");
  Served s(dir, site);
  {
    ProjectLockOptions o;
    o.command = "strata process --layer L1";
    const ProjectLock held(site, o);
    const auto r = s.post("/api/units", json{{"code", "950"}});
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 409);
    EXPECT_NE(error_message(r).find("strata process --layer L1"), std::string::npos) << r->body;
  }
  EXPECT_EQ(s.post("/api/units", json{{"code", "950"}})->status, 201);
}

TEST_F(Serve, AViewerScreenReadsButWritesNothing) {
  const fs::path dir = folder("viewer"), site = copy_template(dir / "site");
  Served s(dir, site, {"--role", "viewer"});
  EXPECT_EQ(s.get("/api/session").at("role"), "viewer");
  EXPECT_EQ(s.get("/api/units").size(), 1u);
  auto r = s.post("/api/units", json{{"code", "960"}});
  EXPECT_EQ(r->status, 403);
  EXPECT_NE(error_message(r).find("recorder"), std::string::npos) << r->body;
  r = s.post("/api/layers/L1/process", json::object());
  EXPECT_EQ(r->status, 403);
  EXPECT_NE(error_message(r).find("supervisor"), std::string::npos) << r->body;
}

TEST_F(Serve, TheSiteNetworkIsRefusedUntilAccountsExist) {
  const fs::path dir = folder("listen"), site = copy_template(dir / "site");
  const auto r = run_strata({"serve", site.string(), "--listen", "0.0.0.0:0"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("loopback"), std::string::npos) << r.err;
  EXPECT_EQ(test::line_count(r.err), 1) << r.err;
  const auto bad = run_strata({"serve", site.string(), "--listen", "8720"});
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("8720"), std::string::npos) << bad.err;
}

// A layer whose photos are uploaded and processed through the API, its progress
// followed as the browser follows it; the same records and products as the command
// line's processing of the same photos (the shared template).
TEST_F(Serve, ALayerUploadedAndProcessedThroughTheApiEqualsTheCommandLines) {
  const fs::path dir = folder("process"), site = dir / "site";
  const fs::path data = shared_ / "data";
  ASSERT_EQ(run_strata({"-q", "init", site.string(), "--crs", "EPSG:32636"}).exit_code, 0);
  Served s(dir, site);
  ASSERT_EQ(s.post("/api/units", json{{"code", "101"}})->status, 201);
  ASSERT_EQ(s.post("/api/layers", json{{"name", "L1"}, {"unit", "101"}})->status, 201);
  for (const auto& photo : test::layer_photos(data, "L1")) {
    const auto r = s.upload("L1", fs::path(photo).filename().string(), file_bytes(photo));
    ASSERT_EQ(r->status, 201) << photo << ": " << r->body;
  }
  // Sent again (a resumed upload): already there, nothing added.
  const auto again = s.upload("L1", fs::path(test::layer_photos(data, "L1").front()).filename().string(),
                              file_bytes(test::layer_photos(data, "L1").front()));
  EXPECT_EQ(again->status, 200) << again->body;
  EXPECT_TRUE(json::parse(again->body).at("already_present").get<bool>());
  // The markers as make_project records them (their import is not in the API yet).
  const fs::path clicks = dir / "gcp_L1.txt";
  test::write_gcp_lines_of(data / "gcp_list.txt", "L1_", clicks);
  ASSERT_EQ(run_strata({"-q", "import", "markers", site.string(), clicks.string(), "--format", "odm"}).exit_code, 0);
  ASSERT_EQ(run_strata({"-q", "import", "markers", site.string(), (data / "markers.csv").string()}).exit_code, 0);

  auto r = s.post("/api/layers/L1/process", json::object());
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string job = json::parse(r->body).at("id");
  // A second start while it runs is refused naming the job.
  const auto second = s.post("/api/layers/L1/process", json::object());
  EXPECT_EQ(second->status, 409);
  EXPECT_NE(error_message(second).find("job " + job), std::string::npos) << second->body;

  std::string stream;
  const auto events = s.client().Get(("/api/jobs/" + job + "/events").c_str(), [&](const char* d, std::size_t n) {
    stream.append(d, n);
    return true;
  });
  ASSERT_TRUE(events);
  // Progress of several stages with counts that grow, then one end event, last.
  std::regex progress(R"(event: progress\ndata: (\{[^\n]*\}))");
  std::set<std::string> stages;
  int progress_events = 0;
  for (auto it = std::sregex_iterator(stream.begin(), stream.end(), progress); it != std::sregex_iterator(); ++it) {
    const json p = json::parse((*it)[1].str());
    stages.insert(p.at("stage"));
    EXPECT_LE(p.at("done").get<std::size_t>(), p.at("total").get<std::size_t>());
    ++progress_events;
  }
  EXPECT_GE(stages.size(), 3u) << stream.substr(0, 2000);
  EXPECT_GE(progress_events, 6);
  const auto end = stream.rfind("event: end\ndata: ");
  ASSERT_NE(end, std::string::npos) << stream.substr(stream.size() > 2000 ? stream.size() - 2000 : 0);
  const json ended = json::parse(stream.substr(end + 17, stream.find('\n', end + 17) - end - 17));
  EXPECT_EQ(ended.at("state"), "done") << ended.dump();
  EXPECT_EQ(s.get("/api/jobs/" + job).at("state"), "done");

  // The same figures and products as the command line's run on the same photos.
  const json api_layer = s.get("/api/layers/L1");
  EXPECT_TRUE(api_layer.at("products").get<bool>());
  s.process().kill_now();
  const auto cli_info = run_strata({"process", (shared_ / "template").string(), "--layer", "L1", "--json"});
  const auto api_info = run_strata({"process", site.string(), "--layer", "L1", "--json"});
  ASSERT_EQ(cli_info.exit_code, 0) << cli_info.err;
  ASSERT_EQ(api_info.exit_code, 0) << api_info.err;
  const json a = json::parse(api_info.out), b = json::parse(cli_info.out);
  for (const char* key : {"images_registered", "points", "observations", "reprojection_rmse_px", "cameras",
                          "control_rmse", "check_rmse", "markers"}) {
    EXPECT_EQ(a.at(key), b.at(key)) << key;
  }
  EXPECT_EQ(file_bytes(site / "products" / "L1" / "dtm.tif"), file_bytes(shared_ / "template" / "products" / "L1" / "dtm.tif"));
  EXPECT_EQ(test::integrity(site / "project.gpkg"), "ok");
}

// Sends the headers of a photo upload and `sent` bytes of its body, then leaves the
// connection open (the server is waiting for the rest). Returns the socket.
int start_partial_upload(int port, const std::string& token, const std::string& body, std::size_t sent) {
  const int fd = connect_to(port);
  const std::string head = "POST /api/layers/L1/photos?name=partial.jpg HTTP/1.1\r\nHost: 127.0.0.1:" +
                           std::to_string(port) + "\r\nX-CSRF-Token: " + token +
                           "\r\nContent-Type: application/octet-stream\r\nContent-Length: " +
                           std::to_string(body.size()) + "\r\n\r\n";
  const std::string part = head + body.substr(0, sent);
  if (::send(fd, part.data(), part.size(), 0) != ssize_t(part.size())) throw std::runtime_error("send failed");
  return fd;
}

// Killed (SIGKILL) in the middle of an upload: nothing recorded, media/ as it was, the
// half-received file removed at the next start, and the photo then uploads whole.
TEST_F(Serve, AServerKilledDuringAnUploadLosesNothing) {
  const fs::path dir = folder("kill_upload"), site = dir / "site";
  ASSERT_EQ(run_strata({"-q", "init", site.string(), "--crs", "EPSG:32636"}).exit_code, 0);
  ASSERT_EQ(run_strata({"-q", "unit", "add", site.string(), "101"}).exit_code, 0);
  ASSERT_EQ(run_strata({"-q", "layer", "add", site.string(), "L1", "--unit", "101"}).exit_code, 0);
  const test::ProjectState before = test::project_state(site);
  const std::string photo = file_bytes(test::layer_photos(shared_ / "data", "L1").front());
  {
    Served s(dir, site);
    const int fd = start_partial_upload(s.port(), s.get("/api/session").at("csrf_token"), photo, photo.size() / 2);
    // The server has the first half in cache/uploads/ when it dies.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    bool receiving = false;
    while (!receiving && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      if (fs::exists(site / "cache" / "uploads")) {
        for (const auto& e : fs::recursive_directory_iterator(site / "cache" / "uploads")) {
          receiving = receiving || (e.is_regular_file() && e.file_size() > 0);
        }
      }
    }
    EXPECT_TRUE(receiving) << "the upload never reached cache/uploads/";
    s.process().kill_now();
    ::close(fd);
  }
  EXPECT_EQ(test::project_state(site), before);
  EXPECT_EQ(test::integrity(site / "project.gpkg"), "ok");
  Served again(dir, site);
  EXPECT_FALSE(fs::exists(site / "cache" / "uploads")) << "the cut-off upload was not removed";
  const auto r = again.upload("L1", "partial.jpg", photo);
  EXPECT_EQ(r->status, 201) << r->body;
  EXPECT_EQ(again.get("/api/layers/L1").at("photos"), 1);
}

// Killed (SIGKILL) while a layer processes: the database sound, media/ intact, and the
// job started again by the next server, which does not recompute the stages done.
TEST_F(Serve, AServerKilledWhileProcessingResumesTheJobAtItsNextStart) {
  const fs::path dir = folder("kill_process"), site = dir / "site";
  // The same photos and markers as the shared project, not processed.
  const fs::path fresh = test::shared_project("serve_unprocessed", 1, 12, 5, std::nullopt);
  test::copy_scene(fresh / "template", site);
  const std::string media_before = test::project_state(site).media;
  {
    Served s(dir, site);
    const auto r = s.post("/api/layers/L1/process", json::object());
    ASSERT_EQ(r->status, 202) << r->body;
    // Killed once the alignment is committed and the dense surface has begun.
    std::string stream;
    s.client().Get("/api/jobs/1/events", [&](const char* d, std::size_t n) {
      stream.append(d, n);
      return stream.find("dense surface") == std::string::npos;
    });
    ASSERT_NE(stream.find("dense surface"), std::string::npos) << stream.substr(0, 3000);
    s.process().kill_now();
  }
  EXPECT_EQ(test::integrity(site / "project.gpkg"), "ok");
  EXPECT_EQ(test::project_state(site).media, media_before);
  ASSERT_TRUE(fs::exists(site / "cache" / "server" / "job.json"));

  Served again(dir, site);
  const json jobs = again.get("/api/jobs");
  ASSERT_EQ(jobs.size(), 1u) << jobs.dump();
  EXPECT_EQ(jobs[0].at("layer"), "L1");
  std::string stream;
  again.client().Get(("/api/jobs/" + jobs[0].at("id").get<std::string>() + "/events").c_str(),
                     [&](const char* d, std::size_t n) {
                       stream.append(d, n);
                       return true;
                     });
  EXPECT_NE(stream.find("alignment up to date, not recomputed"), std::string::npos) << stream.substr(0, 3000);
  EXPECT_NE(stream.find("\"state\":\"done\""), std::string::npos) << stream.substr(stream.size() > 3000 ? stream.size() - 3000 : 0);
  EXPECT_TRUE(again.get("/api/layers/L1").at("products").get<bool>());
  EXPECT_FALSE(fs::exists(site / "cache" / "server" / "job.json"));
}

}  // namespace
}  // namespace strata
