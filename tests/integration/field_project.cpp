#include "integration/field_project.hpp"

#include <sqlite3.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <stdexcept>
#include <thread>

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

namespace fs = std::filesystem;

namespace strata::test {
namespace {

void require(const CommandResult& r, const std::string& what) {
  if (r.exit_code != 0) throw std::runtime_error(what + " failed: " + r.err);
}

struct Connection {
  explicit Connection(const fs::path& path) {
    if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK)
      throw std::runtime_error("cannot open " + path.string());
  }
  ~Connection() { sqlite3_close(db); }
  std::vector<std::vector<std::string>> query(const std::string& sql) const {
    sqlite3_stmt* st = nullptr;
    if (sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr) != SQLITE_OK)
      throw std::runtime_error(std::string("cannot prepare ") + sql + ": " + sqlite3_errmsg(db));
    std::vector<std::vector<std::string>> rows;
    while (sqlite3_step(st) == SQLITE_ROW) {
      std::vector<std::string> row;
      for (int c = 0; c < sqlite3_column_count(st); ++c) {
        const auto* p = static_cast<const char*>(sqlite3_column_blob(st, c));
        row.emplace_back(p ? std::string(p, std::size_t(sqlite3_column_bytes(st, c))) : "NULL");
      }
      rows.push_back(std::move(row));
    }
    sqlite3_finalize(st);
    return rows;
  }
  sqlite3* db = nullptr;
};

}  // namespace

void synth(const fs::path& out, int stages, int photos, int seed) {
  require(run_strata({"-q", "synth", out.string(), "--size", "small", "--stages", std::to_string(stages), "--photos",
                      std::to_string(photos), "--width", "800", "--seed", std::to_string(seed)}),
          "synth");
}

fs::path shared_project(const std::string& name, int layers, int photos, int seed,
                        const std::optional<std::vector<std::string>>& process_l1) {
  std::string parameters = "layers " + std::to_string(layers) + " photos " + std::to_string(photos) + " seed " +
                           std::to_string(seed);
  if (process_l1) {
    parameters += " process";
    for (const auto& a : *process_l1) parameters += " " + a;
  }
  return shared_scene(name, parameters, [&](const fs::path& dir) {
    synth(dir / "data", 1, photos, seed);
    make_project(dir / "template", dir / "data", layers);
    if (!process_l1) return;
    std::vector<std::string> args = {"-q", "process", (dir / "template").string(), "--layer", "L1"};
    args.insert(args.end(), process_l1->begin(), process_l1->end());
    require(run_strata(args), "process");
  });
}

std::vector<std::string> layer_photos(const fs::path& data, const std::string& layer) {
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(data / "photos" / layer)) files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  return files;
}

void make_project(const fs::path& site, const fs::path& data, int layers) {
  require(run_strata({"-q", "init", site.string(), "--crs", "EPSG:32636"}), "init");
  for (int k = 1; k <= layers; ++k) {
    const std::string unit = std::to_string(100 + k), layer = "L" + std::to_string(k);
    require(run_strata({"-q", "unit", "add", site.string(), unit}), "unit add");
    require(run_strata({"-q", "layer", "add", site.string(), layer, "--unit", unit}), "layer add");
    std::vector<std::string> import = {"-q", "import", "photos", site.string(), "--layer", layer};
    for (const auto& f : layer_photos(data, layer)) import.push_back(f);
    require(run_strata(import), "import photos");
    // The generator's clicks on this layer's photos: the small layer's coded targets
    // are too few pixels wide to be found, so the markers are guided, as in the field.
    const fs::path clicks = site.parent_path() / (site.filename().string() + "_gcp_" + layer + ".txt");
    write_gcp_lines_of(data / "gcp_list.txt", layer + "_", clicks);
    require(run_strata({"-q", "import", "markers", site.string(), clicks.string(), "--format", "odm"}),
            "import clicks");
  }
  require(run_strata({"-q", "import", "markers", site.string(), (data / "markers.csv").string()}), "import markers");
}

std::string database_rows(const fs::path& db_path, const std::vector<std::string>& tables) {
  const Connection c(db_path);
  std::vector<std::string> names = tables;
  if (names.empty()) {
    for (const auto& t : c.query("SELECT name FROM sqlite_master WHERE type='table' ORDER BY name")) names.push_back(t[0]);
  }
  std::string out;
  for (const auto& table : names) {
    out += "[" + table + "]\n";
    for (const auto& row : c.query("SELECT * FROM \"" + table + "\" ORDER BY rowid")) {
      for (const auto& v : row) out += v + "|";
      out += "\n";
    }
  }
  return out;
}

std::string integrity(const fs::path& db_path) {
  std::string out;
  for (const auto& row : Connection(db_path).query("PRAGMA integrity_check")) out += row[0];
  return out;
}

ProjectState project_state(const fs::path& site) {
  return {database_rows(site / "project.gpkg"), tree_fingerprint(site / "media")};
}

Background::Background(const fs::path& scratch, const std::vector<std::string>& args) {
  static int serial = 0;
  const std::string stem = "background" + std::to_string(++serial);
  out_ = scratch / (stem + ".out");
  err_ = scratch / (stem + ".err");
  const std::string exe = strata_exe().string();
  pid_ = fork();
  if (pid_ == 0) {
    const int out = ::open(out_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int err = ::open(err_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (out < 0 || err < 0) _exit(126);
    dup2(out, 1);
    dup2(err, 2);
    std::vector<char*> argv{const_cast<char*>(exe.c_str())};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(exe.c_str(), argv.data());
    _exit(127);
  }
  if (pid_ < 0) throw std::runtime_error("fork failed");
}

Background::~Background() {
  if (!done_) kill_now();
}

bool Background::running() {
  if (done_) return false;
  const pid_t r = waitpid(pid_, &status_, WNOHANG);
  if (r == pid_) done_ = true;
  return !done_;
}

CommandResult Background::wait() {
  if (!done_) {
    waitpid(pid_, &status_, 0);
    done_ = true;
  }
  CommandResult r;
  r.exit_code = WIFEXITED(status_) ? WEXITSTATUS(status_) : 128 + WTERMSIG(status_);
  r.out = read_text(out_);
  r.err = read_text(err_);
  return r;
}

void Background::kill_now() {
  if (done_) return;
  ::kill(pid_, SIGKILL);
  waitpid(pid_, &status_, 0);
  done_ = true;
}

bool wait_for_lock(const fs::path& site, Background& holder, double timeout_s) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  const std::string mine = "pid=" + std::to_string(holder.pid()) + "\n";
  while (std::chrono::steady_clock::now() < deadline) {
    if (read_text(site / "project.lock").rfind(mine, 0) == 0) return true;
    if (!holder.running()) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return false;
}

int line_count(const std::string& text) {
  int n = int(std::count(text.begin(), text.end(), '\n'));
  if (!text.empty() && text.back() != '\n') ++n;
  return n;
}

}  // namespace strata::test
