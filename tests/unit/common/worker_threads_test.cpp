#include "common/worker_threads.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <vector>

namespace {

// Every job runs once, whatever the number of threads asked (0 and 1: this thread alone).
TEST(WorkerThreads, EveryJobRunsOnce) {
  for (int threads : {0, 1, 2, 8}) {
    std::vector<std::atomic<int>> runs(200);
    std::atomic<int> next{0};
    common::run_workers(
        threads, [&] {
          for (int j; (j = next++) < 200;) ++runs[static_cast<std::size_t>(j)];
        },
        [] {});
    for (const auto& r : runs) EXPECT_EQ(r.load(), 1) << threads << " threads";
  }
}

// A job that throws in a worker reaches the caller, after every thread has joined, and the
// others stop taking jobs: no std::terminate, no job left running.
TEST(WorkerThreads, AJobThatThrowsIsRethrownAndTheOthersStop) {
  std::atomic<int> next{0}, ran{0};
  const auto work = [&] {
    for (int j; (j = next++) < 100000;) {
      if (j == 10) throw std::runtime_error("job 10 failed");
      ++ran;
    }
  };
  try {
    common::run_workers(4, work, [&] { next = 100000; });
    FAIL() << "the exception was lost";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "job 10 failed");
  }
  EXPECT_LT(ran.load(), 100000 - 1) << "the other workers went on to the end";
}

}  // namespace
