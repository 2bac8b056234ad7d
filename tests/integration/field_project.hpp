#pragma once
// Helpers of the hardening tests (docs/reliability.md): a small synthetic project made once and
// copied per test, a snapshot of everything a project records (to show a refused
// command changed nothing), and strata commands run in the background.
#include "support/shared_scene.hpp"
#include "support/test_support.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <sys/types.h>

namespace strata::test {

// `strata synth OUT --size small` with a layer of `photos` photos per stage; throws
// std::runtime_error when it fails.
void synth(const std::filesystem::path& out, int stages, int photos, int seed);

// A project at `site` with units 101..10k, layers L1..Lk (one per synthetic layer of
// `data`, k = layers), their photos, the generator's clicks on them and the surveyed
// markers.
void make_project(const std::filesystem::path& site, const std::filesystem::path& data, int layers);

// A synthetic excavation of one stage, `data/` (synth(1, photos, seed)), and a project of its
// `layers` first layers, `template/` (make_project), whose L1 is then processed with
// `strata process template --layer L1 PROCESS_ARGS...` when `process_l1` is given:
// made once and shared by every test process (support/shared_scene.hpp). Read it; copy
// what a test changes (copy_scene). Throws std::runtime_error when a step fails.
std::filesystem::path shared_project(const std::string& name, int layers, int photos, int seed,
                                     const std::optional<std::vector<std::string>>& process_l1);

// Every row of the given tables (default: every table) of project.gpkg, as text, in
// a fixed order.
std::string database_rows(const std::filesystem::path& db_path, const std::vector<std::string>& tables = {});
// PRAGMA integrity_check ("ok" when sound).
std::string integrity(const std::filesystem::path& db_path);

// What a project records: its rows and the files of media/ (size and SHA-256).
struct ProjectState {
  std::string rows;
  std::string media;
  bool operator==(const ProjectState& o) const { return rows == o.rows && media == o.media; }
};
ProjectState project_state(const std::filesystem::path& site);

// Photo files of one synthetic layer, sorted.
std::vector<std::string> layer_photos(const std::filesystem::path& data, const std::string& layer);

// A strata command running in the background, its stdout and stderr in files.
class Background {
 public:
  Background(const std::filesystem::path& scratch, const std::vector<std::string>& args);
  ~Background();  // kills the command if it still runs
  Background(const Background&) = delete;
  Background& operator=(const Background&) = delete;

  pid_t pid() const { return pid_; }
  const std::filesystem::path& stdout_path() const { return out_; }
  const std::filesystem::path& stderr_path() const { return err_; }
  bool running();
  CommandResult wait();
  void kill_now();  // SIGKILL, then reaps it

 private:
  pid_t pid_ = -1;
  std::filesystem::path out_, err_;
  int status_ = 0;
  bool done_ = false;
};

// Waits until `site`'s lock file names `pid` as the holder (the command has the
// project), or the command ended; false when that did not happen in `timeout_s`.
bool wait_for_lock(const std::filesystem::path& site, Background& holder, double timeout_s);

// Number of lines of text, ignoring a final newline.
int line_count(const std::string& text);

}  // namespace strata::test
