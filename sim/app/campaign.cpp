#include "sim/app/campaign.hpp"

#include "servo/config/strict_yaml.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <stdexcept>
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

namespace {

// One run of a campaign as campaign.csv holds it (the line itself, and what the summary needs).
struct CampaignRow {
  std::string line, model;
  int run = 0;
  bool converged = false, diverged = false;
  double error_rise = 0;
  int iterations = 0;
  double translation_mm = 0, rotation_deg = 0;
};

constexpr const char* kCsvHeader =
    "model,run,tx_cm,ty_cm,tz_cm,rx_deg,ry_deg,rz_deg,converged,iterations,final_translation_mm,final_rotation_deg,"
    "decoded_initial,diverged,error_rise,stop_reason";

CampaignRow parse_row(const std::string& line, const std::string& where) {
  std::vector<std::string> f;
  std::size_t a = 0;
  for (int i = 0; i < 15; ++i) {
    const std::size_t b = line.find(',', a);
    if (b == std::string::npos) throw std::invalid_argument(where + ": a row with fewer than 16 fields");
    f.push_back(line.substr(a, b - a));
    a = b + 1;
  }
  CampaignRow r;
  r.line = line;
  r.model = f[0];
  try {
    r.run = std::stoi(f[1]);
    r.converged = f[8] == "1";
    r.iterations = std::stoi(f[9]);
    r.translation_mm = std::stod(f[10]);
    r.rotation_deg = std::stod(f[11]);
    r.diverged = f[13] == "1";
    r.error_rise = std::stod(f[14]);
  } catch (const std::exception&) {
    throw std::invalid_argument(where + ": a row with a malformed number: " + line.substr(0, 80));
  }
  return r;
}

struct CampaignMeta {
  std::string scenario, source, conditions = "none";
  std::uint64_t seed = 0;
  int runs = 0, max_iterations = 0, redrawn = 0, visible_desired = 0, shard_index = 1, shard_count = 1;
  std::vector<std::string> models;
  double scale = 1;
};

bool same_campaign(const CampaignMeta& a, const CampaignMeta& b) {
  return a.scenario == b.scenario && a.source == b.source && a.conditions == b.conditions && a.seed == b.seed && a.runs == b.runs &&
         a.max_iterations == b.max_iterations && a.models == b.models && a.scale == b.scale &&
         a.shard_count == b.shard_count && a.redrawn == b.redrawn && a.visible_desired == b.visible_desired;
}

CampaignMeta read_meta(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw std::invalid_argument(file.string() + ": cannot read (is this a campaign folder?)");
  try {
    const nlohmann::json j = nlohmann::json::parse(in);
    CampaignMeta m;
    m.scenario = j.at("scenario").get<std::string>();
    m.source = j.at("features").get<std::string>();
    m.seed = j.at("seed").get<std::uint64_t>();
    m.runs = j.at("runs").get<int>();
    m.max_iterations = j.at("max_iterations").get<int>();
    m.redrawn = j.at("redrawn").get<int>();
    m.visible_desired = j.at("visible_desired").get<int>();
    m.models = j.at("models").get<std::vector<std::string>>();
    m.scale = j.at("scale").get<double>();
    m.conditions = j.at("conditions").get<std::string>();
    m.shard_index = j.at("shard").at(0).get<int>();
    m.shard_count = j.at("shard").at(1).get<int>();
    if (m.runs < 1 || m.shard_count < 1 || m.shard_index < 1 || m.shard_index > m.shard_count || m.models.empty())
      throw std::invalid_argument("inconsistent values");
    return m;
  } catch (const std::exception& e) {
    throw std::invalid_argument(file.string() + ": not a campaign description (" + config::printable(e.what()) + ")");
  }
}

std::vector<CampaignRow> read_rows(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw std::invalid_argument(file.string() + ": cannot read");
  std::string line;
  if (!std::getline(in, line) || line != kCsvHeader) throw std::invalid_argument(file.string() + ": not a campaign.csv");
  std::vector<CampaignRow> rows;
  while (std::getline(in, line))
    if (!line.empty()) rows.push_back(parse_row(line, file.string()));
  return rows;
}

std::vector<ModelStats> stats_of(const std::vector<std::string>& models, const std::vector<CampaignRow>& rows) {
  std::vector<ModelStats> out;
  for (const std::string& model : models) {
    ModelStats m;
    m.model = model;
    std::vector<double> iters, terr, rerr, rise;
    for (const CampaignRow& r : rows) {
      if (r.model != model) continue;
      ++m.runs;
      m.diverged += r.diverged;
      rise.push_back(r.error_rise);
      if (!r.converged) continue;
      ++m.converged;
      iters.push_back(r.iterations);
      terr.push_back(r.translation_mm);
      rerr.push_back(r.rotation_deg);
    }
    m.worst_translation_mm = terr.empty() ? std::nan("") : *std::max_element(terr.begin(), terr.end());
    m.worst_rotation_deg = rerr.empty() ? std::nan("") : *std::max_element(rerr.begin(), rerr.end());
    m.median_iterations = median(iters);
    m.median_translation_mm = median(terr);
    m.median_rotation_deg = median(rerr);
    m.median_error_rise = median(rise);
    out.push_back(m);
  }
  return out;
}

std::string summarize(const CampaignMeta& meta, const std::vector<CampaignRow>& rows) {
  std::ostringstream md;
  md << "| model | converged | diverged | median iterations | median final error, converged runs (mm / deg) | worst "
        "final error, converged runs (mm / deg) | median rise of the error |\n"
     << "|---|---|---|---|---|---|---|\n";
  for (const ModelStats& m : stats_of(meta.models, rows)) {
    char line[320];
    std::snprintf(line, sizeof line, "| %s | %d/%d (%.0f %%) | %d | %.0f | %.3f / %.4f | %.3f / %.4f | %.3f |\n",
                  m.model.c_str(), m.converged, m.runs, m.runs ? 100.0 * m.converged / m.runs : 0.0, m.diverged,
                  m.median_iterations, m.median_translation_mm, m.median_rotation_deg, m.worst_translation_mm,
                  m.worst_rotation_deg, m.median_error_rise);
    md << line;
  }
  char note[260];
  std::snprintf(note, sizeof note,
                "\n%s, %d initial poses (seed %llu, %d draws redrawn for showing < 80 %% of the %d spots seen at "
                "the desired pose), %s features\n",
                meta.scenario.c_str(), meta.runs, static_cast<unsigned long long>(meta.seed), meta.redrawn,
                meta.visible_desired, meta.source.c_str());
  md << note;
  if (meta.conditions != "none") md << "errors and delays: " << meta.conditions << "\n";
  if (meta.shard_count > 1)
    md << "shard " << meta.shard_index << "/" << meta.shard_count << ": every " << meta.shard_count
       << "th initial pose from pose " << meta.shard_index - 1 << " (`cellsim campaign merge` combines the shards)\n";
  return md.str();
}

void write_campaign(const std::filesystem::path& dir, const CampaignMeta& m, const std::vector<CampaignRow>& rows,
                    const std::string& md) {
  std::filesystem::create_directories(dir);
  std::ofstream csv(dir / "campaign.csv");
  if (!csv) throw std::runtime_error((dir / "campaign.csv").string() + ": cannot write");
  csv << kCsvHeader << "\n";
  for (const auto& r : rows) csv << r.line << "\n";
  nlohmann::json j;
  j["scenario"] = m.scenario;
  j["features"] = m.source;
  j["seed"] = m.seed;
  j["runs"] = m.runs;
  j["max_iterations"] = m.max_iterations;
  j["redrawn"] = m.redrawn;
  j["visible_desired"] = m.visible_desired;
  j["models"] = m.models;
  j["scale"] = m.scale;
  j["conditions"] = m.conditions;
  j["shard"] = {m.shard_index, m.shard_count};
  std::ofstream(dir / "campaign.json") << j.dump(1) << "\n";
  std::ofstream(dir / "summary.md") << md;
}

}  // namespace

std::string describe(const sim::CalibrationErrors& e, const sim::Latency& l) {
  std::ostringstream d;
  d << std::setprecision(6);
  const auto put = [&](const std::string& name, double v) {
    if (v != 0) d << (d.tellp() > 0 ? " " : "") << name << '=' << v;
  };
  for (const auto& [name, v] : sim::error_values(e)) put(name, v);
  if (e.any() && e.seed) put("error_seed", static_cast<double>(*e.seed));
  put("acquisition_frames", l.acquisition_frames);
  put("processing_frames", l.processing_frames);
  put("actuation_s", l.actuation_s);
  return d.tellp() > 0 ? d.str() : "none";
}

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
  // a shard runs every N-th initial pose: the draws above are the same for every shard
  for (std::size_t m = 0; m < o.models.size(); ++m)
    for (int r = 0; r < o.runs; ++r)
      if (r % o.shard_count == o.shard_index - 1) jobs.push_back({m, r, {}});
  std::atomic<std::size_t> next{0}, done{0};
  std::mutex io;
  const auto started = std::chrono::steady_clock::now();  // for the estimate of the time left only
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
      e.errors = o.errors;
      e.latency = o.latency;
      e.divergence_ratio = o.divergence_ratio;
      job.result = run_experiment(cell, e);
      job.result.trace.clear();  // keep memory flat: only the outcome matters here
      const std::size_t n = ++done;
      std::lock_guard<std::mutex> lock(io);
      const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
      const double left = elapsed / static_cast<double>(n) * static_cast<double>(jobs.size() - n);
      std::fprintf(stderr, "\rcampaign %s: %zu/%zu runs, %.0f s, about %.0f s left   ", sc.name.c_str(), n, jobs.size(),
                   elapsed, left);
      if (n == jobs.size()) std::fprintf(stderr, "\n");
    }
  };
  std::vector<std::thread> threads;
  for (int t = 1; t < std::max(1, o.threads); ++t) threads.emplace_back(work);
  work();
  for (auto& t : threads) t.join();

  std::vector<CampaignRow> rows;
  for (std::size_t m = 0; m < o.models.size(); ++m)
    for (const Job& job : jobs) {
      if (job.model != m) continue;
      const auto& r = job.result;
      std::ostringstream line;
      line << std::setprecision(17) << control::to_string(o.models[m]) << ',' << job.run;
      for (double x : offsets[static_cast<std::size_t>(job.run)]) line << ',' << x;
      line << ',' << r.converged << ',' << r.iterations << ',' << 1e3 * r.final_translation_error_m << ','
           << r.final_rotation_error_deg << ',' << r.decoded_initial << ',' << r.diverged << ',' << r.error_rise << ",\""
           << r.stop_reason << "\"";
      rows.push_back(parse_row(line.str(), "campaign"));
    }
  CampaignMeta meta;
  meta.scenario = sc.name;
  meta.seed = o.seed;
  meta.runs = o.runs;
  for (const auto m : o.models) meta.models.push_back(control::to_string(m));
  meta.source = to_string(o.source);
  meta.scale = o.scale;
  meta.conditions = describe(o.errors.value_or(sc.errors), o.latency.value_or(sc.latency));
  meta.max_iterations = o.max_iterations;
  meta.redrawn = redrawn;
  meta.visible_desired = visible_desired;
  meta.shard_index = o.shard_index;
  meta.shard_count = o.shard_count;
  const std::string md = summarize(meta, rows);
  if (!o.out_dir.empty()) write_campaign(o.out_dir, meta, rows, md);
  return md;
}

std::string merge_campaigns(const std::vector<std::filesystem::path>& dirs, const std::filesystem::path& out_dir) {
  if (dirs.empty()) throw std::invalid_argument("campaign merge: no shard folders given");
  std::optional<CampaignMeta> first;
  std::set<int> shards;
  std::vector<CampaignRow> rows;
  for (const auto& dir : dirs) {
    const CampaignMeta meta = read_meta(dir / "campaign.json");
    if (!first) {
      first = meta;
    } else if (!same_campaign(*first, meta)) {
      throw std::invalid_argument((dir / "campaign.json").string() +
                                  ": another campaign than the first folder's (scenario, seed, runs, models, features, "
                                  "scale, iteration cap and shard count must match)");
    }
    if (!shards.insert(meta.shard_index).second)
      throw std::invalid_argument((dir / "campaign.json").string() + ": shard " + std::to_string(meta.shard_index) +
                                  " given twice");
    for (auto& r : read_rows(dir / "campaign.csv")) rows.push_back(std::move(r));
  }
  if (static_cast<int>(shards.size()) != first->shard_count)
    throw std::invalid_argument("campaign merge: " + std::to_string(shards.size()) + " of the " +
                                std::to_string(first->shard_count) + " shards given");
  // the unsharded order: by model (in the campaign's order), then by run
  const auto model_index = [&](const std::string& m) {
    return std::find(first->models.begin(), first->models.end(), m) - first->models.begin();
  };
  std::sort(rows.begin(), rows.end(), [&](const CampaignRow& a, const CampaignRow& b) {
    return std::make_pair(model_index(a.model), a.run) < std::make_pair(model_index(b.model), b.run);
  });
  CampaignMeta merged = *first;
  merged.shard_index = 1;
  merged.shard_count = 1;
  if (rows.size() != merged.models.size() * static_cast<std::size_t>(merged.runs))
    throw std::invalid_argument("campaign merge: " + std::to_string(rows.size()) + " runs found, " +
                                std::to_string(merged.models.size() * static_cast<std::size_t>(merged.runs)) +
                                " expected");
  const std::string md = summarize(merged, rows);
  write_campaign(out_dir, merged, rows, md);
  return md;
}

std::vector<ModelStats> campaign_stats(const std::filesystem::path& dir) {
  const CampaignMeta meta = read_meta(dir / "campaign.json");
  return stats_of(meta.models, read_rows(dir / "campaign.csv"));
}

bool plot_campaign(const std::filesystem::path& dir, const std::string& title) {
  return run_plot_script("plot_campaign.py", dir, title);
}

}  // namespace cellsim
