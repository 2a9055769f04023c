#include "sim/app/campaign.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <random>
#include <sstream>
#include <thread>

namespace cellsim {

namespace {

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

std::string run_campaign(const sim::Cell& cell, const CampaignOptions& o) {
  const sim::Scenario& sc = cell.scenario;
  // The same initial poses for every model. A draw from which the camera does not see at
  // least 80 % of the spots it sees at the desired pose is drawn again: the campaign compares
  // control laws, not whether the object is in view.
  const auto visible = [&](const Eigen::Isometry3d& wTc) {
    int n = 0;
    for (const auto& t : sim::compute_truth(cell, wTc)) n += t.visible;
    return n;
  };
  const int visible_desired = visible(sc.world_T_desired);
  // an arm must reach the pose too (a free-flying camera always does)
  const std::unique_ptr<sim::Robot> probe = sim::make_robot(cell);
  const auto reachable = [&](const Eigen::Isometry3d& wTc) {
    try {
      probe->reset(wTc);
      return true;
    } catch (const std::invalid_argument&) {
      return false;
    }
  };
  std::mt19937_64 rng(o.seed);
  std::vector<std::array<double, 6>> offsets(static_cast<std::size_t>(o.runs));
  int redrawn = 0;
  for (auto& off : offsets) {
    for (int attempt = 0;; ++attempt) {
      for (int i = 0; i < 6; ++i) {
        const double range =
            o.scale * std::max(2.0, std::abs(i < 3 ? sc.initial_translation_cm[i] : sc.initial_rotation_deg[i - 3]));
        off[i] = std::uniform_real_distribution<double>(-range, range)(rng);
      }
      const auto wTc = sim::offset_pose(sc.world_T_desired, {off[0], off[1], off[2]}, {off[3], off[4], off[5]},
                                        sc.offset_frame_rotation_deg);
      if ((visible(wTc) >= 0.8 * visible_desired && reachable(wTc)) || attempt >= 1000) break;
      ++redrawn;
    }
  }
  struct Job {
    std::size_t model;
    int run;
    ExperimentResult result;
  };
  std::vector<Job> jobs;
  for (std::size_t m = 0; m < o.models.size(); ++m)
    for (int r = 0; r < o.runs; ++r) jobs.push_back({m, r, {}});
  std::atomic<std::size_t> next{0}, done{0};
  std::mutex io;
  const auto work = [&] {
    for (std::size_t j; (j = next++) < jobs.size();) {
      Job& job = jobs[j];
      ExperimentOptions e;
      e.servo = o.base;
      e.servo.law.model = o.models[job.model];
      e.source = o.source;
      e.max_iterations = o.max_iterations;
      const auto& off = offsets[static_cast<std::size_t>(job.run)];
      e.initial = sim::offset_pose(sc.world_T_desired, {off[0], off[1], off[2]}, {off[3], off[4], off[5]},
                                   sc.offset_frame_rotation_deg);
      e.noise_seed = o.seed * 1000003 + static_cast<std::uint64_t>(job.run);
      job.result = run_experiment(cell, e);
      job.result.trace.clear();  // keep memory flat: only the outcome matters here
      const std::size_t n = ++done;
      std::lock_guard<std::mutex> lock(io);
      std::fprintf(stderr, "\rcampaign %s: %zu/%zu runs", sc.name.c_str(), n, jobs.size());
      if (n == jobs.size()) std::fprintf(stderr, "\n");
    }
  };
  std::vector<std::thread> threads;
  for (int t = 1; t < std::max(1, o.threads); ++t) threads.emplace_back(work);
  work();
  for (auto& t : threads) t.join();

  std::ostringstream md;
  md << "| model | converged | median iterations | median final error, converged runs (mm / deg) | worst final "
        "error, converged runs (mm / deg) |\n"
     << "|---|---|---|---|---|\n";
  std::ofstream csv;
  if (!o.out_dir.empty()) {
    std::filesystem::create_directories(o.out_dir);
    csv.open(o.out_dir / "campaign.csv");
    csv << "model,run,tx_cm,ty_cm,tz_cm,rx_deg,ry_deg,rz_deg,converged,iterations,final_translation_mm,final_rotation_deg,"
           "decoded_initial,stop_reason\n";
  }
  for (std::size_t m = 0; m < o.models.size(); ++m) {
    int converged = 0;
    std::vector<double> iters, terr, rerr;
    for (const Job& job : jobs) {
      if (job.model != m) continue;
      const auto& r = job.result;
      if (r.converged) {
        ++converged;
        iters.push_back(r.iterations);
        terr.push_back(1e3 * r.final_translation_error_m);
        rerr.push_back(r.final_rotation_error_deg);
      }
      if (csv.is_open()) {
        csv << control::to_string(o.models[m]) << ',' << job.run;
        for (double x : offsets[static_cast<std::size_t>(job.run)]) csv << ',' << x;
        csv << ',' << r.converged << ',' << r.iterations << ',' << 1e3 * r.final_translation_error_m << ','
            << r.final_rotation_error_deg << ',' << r.decoded_initial << ",\"" << r.stop_reason << "\"\n";
      }
    }
    const double worst_t = terr.empty() ? std::nan("") : *std::max_element(terr.begin(), terr.end());
    const double worst_r = rerr.empty() ? std::nan("") : *std::max_element(rerr.begin(), rerr.end());
    char line[320];
    std::snprintf(line, sizeof line, "| %s | %d/%d (%.0f %%) | %.0f | %.3f / %.4f | %.3f / %.4f |\n",
                  control::to_string(o.models[m]).c_str(), converged, o.runs, 100.0 * converged / o.runs, median(iters),
                  median(terr), median(rerr), worst_t, worst_r);
    md << line;
  }
  char note[200];
  std::snprintf(note, sizeof note,
                "\n%s, %d initial poses (seed %llu, %d draws redrawn for showing < 80 %% of the %d spots seen at "
                "the desired pose), %s features\n",
                sc.name.c_str(), o.runs, static_cast<unsigned long long>(o.seed), redrawn, visible_desired,
                to_string(o.source).c_str());
  md << note;
  if (!o.out_dir.empty()) std::ofstream(o.out_dir / "summary.md") << md.str();
  return md.str();
}

}  // namespace cellsim
