// The project's write lock (project/project_lock.hpp): one writer at a time, the
// second told who holds it; a lock released on destruction; a wait that ends
// when the holder does.
#include "core/error.hpp"
#include "project/project.hpp"
#include "project/project_lock.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <thread>

#include <unistd.h>

namespace strata {
namespace {

namespace fs = std::filesystem;

// Long enough for the holder's thread to take the lock on a loaded machine, short
// against the wait it must end (seconds).
constexpr double kHoldS = 0.6;
constexpr double kWaitS = 30;

fs::path make_project(const test::ScratchDir& dir) {
  CreateOptions o;
  o.crs = "EPSG:32636";
  Project::create(dir / "site", o);
  return dir / "site";
}

ProjectLockOptions as(const std::string& command, double wait_s = 0) {
  ProjectLockOptions o;
  o.command = command;
  o.wait_s = wait_s;
  return o;
}

TEST(ProjectLock, SecondWriterIsToldWhoHoldsIt) {
  test::ScratchDir dir("lock");
  const fs::path site = make_project(dir);
  auto first = std::make_unique<ProjectLock>(site, as("strata process --layer L2"));
  const auto holder = ProjectLock::holder(site);
  ASSERT_TRUE(holder);
  EXPECT_EQ(holder->pid, long(getpid()));
  EXPECT_EQ(holder->command, "strata process --layer L2");
  try {
    ProjectLock second(site, as("strata import photos --layer L1 a.jpg"));
    FAIL() << "a second writer took the lock";
  } catch (const IoError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind("project is busy: `strata process --layer L2` (pid " + std::to_string(getpid()) + ", since ", 0),
              0u)
        << msg;
    EXPECT_NE(msg.find("project.lock"), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
  first.reset();
  EXPECT_FALSE(ProjectLock::holder(site));
  ProjectLock third(site, as("strata unit add 101"));  // released: free again
  EXPECT_EQ(ProjectLock::holder(site)->command, "strata unit add 101");
}

TEST(ProjectLock, WaitingWriterTakesItWhenTheHolderEnds) {
  test::ScratchDir dir("lock_wait");
  const fs::path site = make_project(dir);
  auto first = std::make_unique<ProjectLock>(site, as("strata process --layer L1"));
  std::thread release([&] {
    std::this_thread::sleep_for(std::chrono::duration<double>(kHoldS));
    first.reset();
  });
  const auto start = std::chrono::steady_clock::now();
  ProjectLock second(site, as("strata volume", kWaitS));
  const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  release.join();
  EXPECT_GE(waited, kHoldS * 0.9);
  EXPECT_LT(waited, kWaitS);
  EXPECT_EQ(ProjectLock::holder(site)->command, "strata volume");
}

TEST(ProjectLock, RefusesANegativeWait) {
  test::ScratchDir dir("lock_bad");
  const fs::path site = make_project(dir);
  EXPECT_THROW(ProjectLock(site, as("strata volume", -1)), InputError);
  EXPECT_FALSE(fs::exists(site / ProjectLock::kFileName));
}

TEST(ProjectLock, FolderWithoutAProjectIsLeftAlone) {
  test::ScratchDir dir("lock_none");
  ProjectLock lock(dir.path(), as("strata unit add 101"));
  EXPECT_FALSE(fs::exists(dir / ProjectLock::kFileName));
}

}  // namespace
}  // namespace strata
