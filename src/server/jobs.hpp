#pragma once
// Long work of the field station (processing a layer) as jobs: one at a time, since
// each holds the project's write lock; each keeps its events (progress, log lines, the
// end) for every page that follows it, from the first event, so a page opened late
// or reconnected sees the whole job. A closed browser does not stop a job.
#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace strata {

enum class JobState { running, done, failed, cancelled };
const char* to_string(JobState s);

struct JobEvent {
  long id = 0;       // 1, 2, ... within the job (the SSE event id)
  std::string type;  // progress | log | end
  std::string data;  // JSON
};

class Job {
 public:
  Job(std::string id, std::string kind, std::string layer);

  const std::string& id() const { return id_; }
  const std::string& kind() const { return kind_; }
  const std::string& layer() const { return layer_; }

  void progress(const std::string& stage, std::size_t done, std::size_t total, double elapsed_s);
  void log_line(const std::string& level, const std::string& message);
  void finish(JobState state, const std::string& message);  // pushes the end event

  JobState state() const;
  nlohmann::json describe() const;  // the Job of docs/api.yaml

  // The events after `after` (all of them after 0), waiting up to `timeout` for one
  // when there is none yet. False once the job has ended and `after` is its last event.
  bool events_after(long after, std::vector<JobEvent>& out, std::chrono::milliseconds timeout) const;

 private:
  void push(std::string type, std::string data);  // with mutex_ held
  nlohmann::json describe_locked() const;

  const std::string id_, kind_, layer_;
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  JobState state_ = JobState::running;
  std::string stage_, message_;
  std::size_t done_ = 0, total_ = 0;
  std::vector<JobEvent> events_;
  static constexpr std::size_t kMaxEvents = 20000;  // then progress events are no longer kept (logs and the end are)
};

class JobRunner {
 public:
  ~JobRunner();  // asks a running job to stop and waits for it

  // Runs `work` on a thread of its own as the job `kind` of `layer`. The caller has
  // checked that no job runs (running()). `work` returns the summary of a job done;
  // it throws Cancelled when stopped, anything else when it failed.
  std::shared_ptr<Job> start(const std::string& kind, const std::string& layer,
                             std::function<std::string(Job&)> work);

  std::shared_ptr<Job> running() const;  // the job running now, if any
  std::shared_ptr<Job> find(const std::string& id) const;
  std::vector<std::shared_ptr<Job>> list() const;  // newest first
  bool cancel(const std::string& id);  // false when the job is not running
  void stop();  // asks a running job to stop and waits for it

 private:
  mutable std::mutex mutex_;
  std::vector<std::shared_ptr<Job>> jobs_;
  std::shared_ptr<Job> running_;
  std::thread thread_;
  long next_id_ = 1;
};

}  // namespace strata
