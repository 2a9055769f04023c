#include "common/output_file.hpp"
#include "common/worker_threads.hpp"
#include "common/progress.hpp"
#include "sim/cell/build_cell.hpp"
#include "sim/experiment/divergence_search.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <mutex>
#include <random>
#include <set>

#include "sim/render/cell.hpp"

namespace experiment {

namespace {

using Spots = std::vector<std::array<int, 2>>;

// The spots the camera sees at the desired pose with the whole pattern lit.
std::set<std::array<int, 2>> seen_at_desired(const sim::Scenario& scenario) {
  sim::Scenario all = scenario;
  all.projector.only_spots.clear();
  const auto cell = sim::build_cell(sim::resolve(all));
  std::set<std::array<int, 2>> seen;
  for (const auto& t : sim::compute_truth(*cell, scenario.world_T_desired))
    if (t.visible) seen.insert({t.row, t.col});
  return seen;
}

// A quincunx of seen spots: four corners of a rectangle and its centre.
Spots draw_quincunx(const std::set<std::array<int, 2>>& seen, std::mt19937_64& rng) {
  const std::vector<std::array<int, 2>> pool(seen.begin(), seen.end());
  for (int attempt = 0; attempt < 1000; ++attempt) {
    const auto centre = pool[std::uniform_int_distribution<std::size_t>(0, pool.size() - 1)(rng)];
    const int dr = std::uniform_int_distribution<int>(2, 7)(rng), dc = std::uniform_int_distribution<int>(2, 7)(rng);
    Spots s{{centre[0] - dr, centre[1] - dc}, {centre[0] - dr, centre[1] + dc}, {centre[0] + dr, centre[1] - dc},
            {centre[0] + dr, centre[1] + dc}, centre};
    if (std::all_of(s.begin(), s.end(), [&](const auto& rc) { return seen.count(rc) > 0; })) return s;
  }
  return {};
}

int visible_count(const sim::Cell& cell, const Eigen::Isometry3d& wTc) {
  int n = 0;
  for (const auto& t : sim::compute_truth(cell, wTc)) n += t.visible;
  return n;
}

ExperimentResult run(const sim::Cell& cell, control::InteractionModel model, const DivergenceSearchOptions& o,
                     const Eigen::Isometry3d& initial) {
  ExperimentOptions e;
  e.servo = servo_config_for(cell);
  e.servo.law.model = model;
  e.servo.law.z_hat_m = o.z_hat_m;
  e.servo.law.gain = control::Gain{o.gain, o.gain, 0};
  e.source = loop::FeatureSource::kIdeal;
  e.max_iterations = o.max_iterations;
  e.servo.divergence_ratio = 2;
  e.initial = initial;
  ExperimentResult r = run_experiment(cell, e);
  r.trace.clear();
  return r;
}

void judge(DivergenceCandidate& c) {
  const auto& k = c.constant_depth;
  if (!k.diverged) {
    c.why_not = "constant depth: " + k.stop_reason;
  } else if (k.final_translation_error_m <= c.initial_translation_m) {
    c.why_not = "constant depth: diverged without moving away";
  } else if (!c.desired.converged) {
    c.why_not = "desired: " + c.desired.stop_reason;
  } else if (!c.current.converged) {
    c.why_not = "current: " + c.current.stop_reason;
  } else if (c.current.iterations >= c.desired.iterations) {
    c.why_not = "current not faster than desired";
  } else {
    c.kept = true;
  }
}

void write_outputs(const sim::Scenario& sc, const DivergenceSearchOptions& o, const DivergenceSearchResult& res) {
  common::make_output_folder(o.out_dir);
  common::OutputStream csv;
  csv.open(o.out_dir / "candidates.csv", "table");
  csv << "try,spots,tx_cm,ty_cm,tz_cm,rx_deg,ry_deg,rz_deg,kept,displacement,constant_depth,constant_depth_iterations,"
         "desired,desired_iterations,current,current_iterations,why_not\n"
      << std::setprecision(10);
  const auto outcome = [](const ExperimentResult& r) {
    return r.converged ? "converged" : r.diverged ? "diverged" : r.stop_reason.empty() ? "not run" : "stopped";
  };
  for (const auto& c : res.candidates) {
    csv << c.index << ",\"";
    for (std::size_t i = 0; i < c.spots.size(); ++i) csv << (i ? " " : "") << c.spots[i][0] << ':' << c.spots[i][1];
    csv << '"';
    for (double x : c.offset) csv << ',' << x;
    csv << ',' << c.kept << ',' << c.displacement << ',' << outcome(c.constant_depth) << ','
        << c.constant_depth.iterations << ',' << outcome(c.desired) << ',' << c.desired.iterations << ','
        << outcome(c.current) << ',' << c.current.iterations << ",\"" << c.why_not << "\"\n";
  }
  csv.close();
  if (res.best < 0) return;
  const auto& b = res.candidates[static_cast<std::size_t>(res.best)];
  common::OutputStream y;
  y.open(o.out_dir / "best.yaml", "scenario excerpt");
  y << std::setprecision(6) << "# cellsim fig5-search " << sc.file.filename().string() << " --tries " << o.tries
    << " --seed " << o.seed << ": try " << b.index << "\n# put these into the scenario's projector: and initial_offset:\n"
    << "only_spots: [";
  for (std::size_t i = 0; i < b.spots.size(); ++i) y << (i ? ", " : "") << '[' << b.spots[i][0] << ", " << b.spots[i][1] << ']';
  y << "]\ninitial_offset:\n  translation_cm: [" << b.offset[0] << ", " << b.offset[1] << ", " << b.offset[2]
    << "]\n  rotation_deg: [" << b.offset[3] << ", " << b.offset[4] << ", " << b.offset[5] << "]\n";
  y.close();
}

}  // namespace

DivergenceSearchResult search_divergence(const sim::Scenario& scenario, const DivergenceSearchOptions& o) {
  if (o.tries < 1 || o.tries > 100000) throw std::invalid_argument("fig5-search: --tries must be in [1, 100000]");
  const auto seen = seen_at_desired(scenario);
  if (o.vary_spots && seen.size() < 5)
    throw std::invalid_argument(scenario.file.string() + ": fewer than 5 spots seen at the desired pose");
  if (!o.out_dir.empty())  // its files, checked before the tries run
    for (const char* file : {"candidates.csv", "best.yaml"}) common::check_output_file(o.out_dir / file, "table");

  // every draw first, from one generator: the result does not depend on the threads
  DivergenceSearchResult res;
  std::mt19937_64 rng(o.seed);
  for (int i = 0; i < o.tries; ++i) {
    DivergenceCandidate c;
    c.index = i;
    c.spots = o.vary_spots ? draw_quincunx(seen, rng) : scenario.projector.only_spots;
    const double limits[6] = {o.max_translation_cm, o.max_translation_cm, o.max_translation_cm,
                              o.max_tilt_deg,       o.max_tilt_deg,       o.max_roll_deg};
    for (int k = 0; k < 6; ++k) c.offset[k] = std::uniform_real_distribution<double>(-limits[k], limits[k])(rng);
    res.candidates.push_back(std::move(c));
  }

  std::atomic<int> next{0}, done{0};
  common::Progress progress("fig5-search", static_cast<std::size_t>(o.tries), "tries");
  const auto work = [&] {
    for (int i; (i = next++) < o.tries;) {
      DivergenceCandidate& c = res.candidates[static_cast<std::size_t>(i)];
      sim::Scenario s = scenario;
      s.projector.only_spots = c.spots;
      const Eigen::Isometry3d initial = sim::offset_pose(s.world_T_desired, {c.offset[0], c.offset[1], c.offset[2]},
                                                         {c.offset[3], c.offset[4], c.offset[5]},
                                                         s.offset_frame_rotation_deg);
      c.initial_translation_m = sim::translation_error(initial, s.world_T_desired);
      const Eigen::Vector3d t(c.offset[0], c.offset[1], c.offset[2]), r(c.offset[3], c.offset[4], c.offset[5]);
      c.displacement = t.norm() / 10 + r.norm() / 10;
      if (c.spots.size() != 5) {
        c.why_not = "no quincunx of seen spots";
      } else if (!s.workspace.contains(initial.translation())) {
        c.why_not = "initial pose outside the workspace";
      } else {
        const auto cell = sim::build_cell(sim::resolve(s));
        if (visible_count(*cell, s.world_T_desired) < 5 || visible_count(*cell, initial) < 5) {
          c.why_not = "the five spots are not all seen from both poses";
        } else {
          c.constant_depth = run(*cell, control::InteractionModel::kDesiredConstantDepth, o, initial);
          if (c.constant_depth.diverged) {
            c.desired = run(*cell, control::InteractionModel::kDesired, o, initial);
            c.current = run(*cell, control::InteractionModel::kCurrent, o, initial);
          }
          judge(c);
        }
      }
      progress.at(static_cast<std::size_t>(++done));
    }
  };
  // a try that throws stops the others from taking one, and is rethrown here
  common::run_workers(o.threads, work, [&] { next = o.tries; });

  for (const auto& c : res.candidates)
    if (c.kept && (res.best < 0 || c.displacement < res.candidates[static_cast<std::size_t>(res.best)].displacement))
      res.best = c.index;
  if (!o.out_dir.empty()) write_outputs(scenario, o, res);
  return res;
}

}  // namespace experiment
