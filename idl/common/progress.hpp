// How much a command says while it works (issue 43, item 4): --quiet, the default, --verbose.
// A process-wide level, set once from the command line like a log level: the libraries'
// results never depend on it, only what they print on stderr. Progress of a long job: on a
// terminal one line rewritten in place (at most 5 times a second); in a log file a line at most
// every 10 s and one at the end, so that a Slurm log or CI output is not a wall of "\r".
#pragma once

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <mutex>
#include <string>

namespace common {

enum class Verbosity { kQuiet, kNormal, kVerbose };

inline Verbosity& verbosity() {
  static Verbosity level = Verbosity::kNormal;
  return level;
}
inline bool quiet() { return verbosity() == Verbosity::kQuiet; }
inline bool verbose() { return verbosity() == Verbosity::kVerbose; }

// "campaign plane: 12/40 runs, 3 s, about 7 s left". Thread-safe.
class Progress {
 public:
  Progress(std::string what, std::size_t total, std::string unit)
      : what_(std::move(what)), unit_(std::move(unit)), total_(total), tty_(::isatty(::fileno(stderr)) == 1),
        start_(Clock::now()) {}
  // `done` of the total are finished (the last one ends the line)
  void at(std::size_t done) {
    if (quiet() || total_ == 0) return;
    std::lock_guard<std::mutex> lock(m_);
    const double t = seconds();
    if (done < total_ && t - said_s_ < (tty_ ? 0.2 : 10.0)) return;
    said_s_ = t;
    say(done, t, done >= total_);
  }
  // the job ended after `done` (a run that converged before its cap)
  void finish(std::size_t done) {
    if (quiet() || total_ == 0) return;
    std::lock_guard<std::mutex> lock(m_);
    say(done, seconds(), true);
  }

 private:
  using Clock = std::chrono::steady_clock;
  void say(std::size_t done, double t, bool last) {
    if (last && ended_) return;
    ended_ = last;
    std::string line = what_ + ": " + std::to_string(done) + "/" + std::to_string(total_) + " " + unit_ + ", " +
                       std::to_string(static_cast<long>(t + 0.5)) + " s";
    if (!last && done > 0)
      line += ", about " + std::to_string(static_cast<long>(t / static_cast<double>(done) *
                                                                static_cast<double>(total_ - done) + 0.5)) + " s left";
    std::fprintf(stderr, "%s%s%s", tty_ ? "\r" : "", line.c_str(), tty_ && !last ? "   " : "\n");
    std::fflush(stderr);
  }
  double seconds() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }
  std::string what_, unit_;
  std::size_t total_;
  bool tty_;
  Clock::time_point start_;
  std::mutex m_;
  double said_s_ = -1e9;
  bool ended_ = false;
};

}  // namespace common
