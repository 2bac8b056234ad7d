#include "server/jobs.hpp"

#include "core/error.hpp"
#include "core/job_hooks.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace strata {

const char* to_string(JobState s) {
  switch (s) {
    case JobState::running: return "running";
    case JobState::done: return "done";
    case JobState::failed: return "failed";
    case JobState::cancelled: return "cancelled";
  }
  return "failed";
}

Job::Job(std::string id, std::string kind, std::string layer)
    : id_(std::move(id)), kind_(std::move(kind)), layer_(std::move(layer)) {}

void Job::push(std::string type, std::string data) {
  if (events_.size() >= kMaxEvents && type == "progress") return;
  events_.push_back({events_.empty() ? 1 : events_.back().id + 1, std::move(type), std::move(data)});
  changed_.notify_all();
}

void Job::progress(const std::string& stage, std::size_t done, std::size_t total, double elapsed_s) {
  std::lock_guard lock(mutex_);
  stage_ = stage;
  done_ = done;
  total_ = total;
  push("progress", nlohmann::json{{"stage", stage}, {"done", done}, {"total", total}, {"elapsed_s", elapsed_s}}.dump());
}

void Job::log_line(const std::string& level, const std::string& message) {
  std::lock_guard lock(mutex_);
  push("log", nlohmann::json{{"level", level}, {"message", message}}.dump());
}

void Job::finish(JobState state, const std::string& message) {
  std::lock_guard lock(mutex_);
  state_ = state;
  message_ = message;
  push("end", describe_locked().dump());
}

JobState Job::state() const {
  std::lock_guard lock(mutex_);
  return state_;
}

nlohmann::json Job::describe_locked() const {
  return {{"id", id_},     {"kind", kind_}, {"layer", layer_}, {"state", to_string(state_)},
          {"stage", stage_}, {"done", done_}, {"total", total_}, {"message", message_}};
}

nlohmann::json Job::describe() const {
  std::lock_guard lock(mutex_);
  return describe_locked();
}

bool Job::events_after(long after, std::vector<JobEvent>& out, std::chrono::milliseconds timeout) const {
  std::unique_lock lock(mutex_);
  const auto newer = [&] { return !events_.empty() && events_.back().id > after; };
  if (!newer() && state_ == JobState::running) changed_.wait_for(lock, timeout, newer);
  for (const auto& e : events_) {
    if (e.id > after) out.push_back(e);
  }
  const long last = events_.empty() ? 0 : events_.back().id;
  return state_ == JobState::running || last > after;
}

JobRunner::~JobRunner() { stop(); }

std::shared_ptr<Job> JobRunner::start(const std::string& kind, const std::string& layer,
                                      std::function<std::string(Job&)> work) {
  std::lock_guard lock(mutex_);
  STRATA_CHECK(!running_, "a job is already running");
  if (thread_.joinable()) thread_.join();  // the previous job's thread has ended its work
  auto job = std::make_shared<Job>(std::to_string(next_id_++), kind, layer);
  jobs_.push_back(job);
  running_ = job;
  clear_cancel();
  // The terminal's progress and log, handed to the job's followers as they happen.
  set_progress_listener([job](const ProgressEvent& e) { job->progress(e.stage, e.done, e.total, e.elapsed_s); });
  set_log_listener([job](log::Level l, std::string_view m) {
    job->log_line(l == log::Level::warning ? "warning" : l == log::Level::error ? "error" : "info", std::string(m));
  });
  thread_ = std::thread([this, job, work = std::move(work)] {
    JobState state = JobState::done;
    std::string message;
    try {
      message = work(*job);
    } catch (const Cancelled&) {
      state = JobState::cancelled;
      message = "cancelled: the project is unchanged by the interrupted step";
    } catch (const Error& e) {
      state = JobState::failed;
      message = e.what();
    } catch (const std::exception& e) {
      state = JobState::failed;
      message = fmt::format("internal error: {}", e.what());
    }
    set_progress_listener({});
    set_log_listener({});
    if (state != JobState::done) log::warn("job {} ({} {}): {}", job->id(), job->kind(), job->layer(), message);
    {
      std::lock_guard lock(mutex_);
      running_.reset();
    }
    job->finish(state, message);
    clear_cancel();
  });
  return job;
}

std::shared_ptr<Job> JobRunner::running() const {
  std::lock_guard lock(mutex_);
  return running_;
}

std::shared_ptr<Job> JobRunner::find(const std::string& id) const {
  std::lock_guard lock(mutex_);
  for (const auto& j : jobs_) {
    if (j->id() == id) return j;
  }
  return nullptr;
}

std::vector<std::shared_ptr<Job>> JobRunner::list() const {
  std::lock_guard lock(mutex_);
  return {jobs_.rbegin(), jobs_.rend()};
}

bool JobRunner::cancel(const std::string& id) {
  std::lock_guard lock(mutex_);
  if (!running_ || running_->id() != id) return false;
  request_cancel();
  return true;
}

void JobRunner::stop() {
  {
    std::lock_guard lock(mutex_);
    if (running_) request_cancel();
  }
  if (thread_.joinable()) thread_.join();
}

}  // namespace strata
