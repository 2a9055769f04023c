// A pool of worker threads for the batch tools (campaigns, decode sweeps, the Fig. 5 search).
#pragma once

#include <algorithm>
#include <exception>
#include <mutex>
#include <system_error>
#include <thread>
#include <vector>

namespace common {

// Runs `work` on `threads` threads, this one among them, and joins them all. The first
// exception a worker throws is rethrown here once every thread has joined, and `on_throw` is
// called (under a lock) when one throws, so that the others stop taking work: an exception left
// in a std::thread would end the process (std::terminate) without a word. When the system
// cannot start a thread, the work runs on those it could.
template <class Work, class OnThrow>
void run_workers(int threads, const Work& work, const OnThrow& on_throw) {
  std::mutex m;
  std::exception_ptr failed;
  const auto guarded = [&] {
    try {
      work();
    } catch (...) {
      const std::lock_guard<std::mutex> lock(m);
      if (!failed) failed = std::current_exception();
      on_throw();
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < std::max(1, threads); ++t) {
    try {
      pool.emplace_back(guarded);
    } catch (const std::system_error&) {
      break;
    }
  }
  guarded();
  for (std::thread& t : pool) t.join();
  if (failed) std::rethrow_exception(failed);
}

}  // namespace common
