// Benchmark driver: runs Google Benchmark, then prints every benchmark's time as a ratio
// against its group's baseline measured in the same run. A benchmark "group/baseline"
// is the reference for all "group/..." benchmarks.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <map>
#include <string>
#include <vector>

namespace {

class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& r : runs) {
      if (r.run_type != Run::RT_Iteration || r.error_occurred) continue;
      const double ns = r.GetAdjustedRealTime() * unit_to_ns(r.time_unit);
      results_.push_back({r.benchmark_name(), ns});
    }
  }
  void Finalize() override {
    ConsoleReporter::Finalize();
    std::map<std::string, double> baseline;
    for (const auto& [name, ns] : results_) {
      const auto slash = name.find('/');
      if (slash != std::string::npos && name.compare(slash + 1, 8, "baseline") == 0) baseline[name.substr(0, slash)] = ns;
    }
    std::printf("\n%-48s %14s %12s\n", "benchmark", "time", "vs baseline");
    for (const auto& [name, ns] : results_) {
      const auto slash = name.find('/');
      const std::string group = slash == std::string::npos ? name : name.substr(0, slash);
      const auto b = baseline.find(group);
      char ratio[32] = "";
      if (b != baseline.end()) std::snprintf(ratio, sizeof ratio, "%.2fx", b->second / ns);
      std::printf("%-48s %11.3f ms %12s\n", name.c_str(), ns / 1e6, ratio);
    }
    std::printf("(ratio = baseline time / time: above 1 is faster than the baseline)\n");
  }

 private:
  static double unit_to_ns(benchmark::TimeUnit u) {
    switch (u) {
      case benchmark::kSecond: return 1e9;
      case benchmark::kMillisecond: return 1e6;
      case benchmark::kMicrosecond: return 1e3;
      default: return 1.0;
    }
  }
  std::vector<std::pair<std::string, double>> results_;
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  return 0;
}
