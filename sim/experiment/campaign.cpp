#include "sim/cell/build_cell.hpp"
#include "sim/experiment/campaign.hpp"

#include "sim/arm/robot_model.hpp"

#include "common/output_file.hpp"
#include "common/progress.hpp"
#include "common/regular_file.hpp"
#include "common/strict_yaml.hpp"
#include "common/worker_threads.hpp"

#include <algorithm>
#include <cerrno>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <stdexcept>
#include <mutex>
#include <random>
#include <sstream>

namespace experiment {

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
  std::string line, model, stop_reason;
  int run = 0;
  bool converged = false, diverged = false;
  double error_rise = 0, max_error_ratio = 0;
  int iterations = 0;
  // the points the law took off their spot's centre (ExperimentResult::off_centre_max, _total)
  long long off_centre_max = 0, off_centre_total = 0;
  double translation_mm = 0, rotation_deg = 0;
};

constexpr const char* kCsvHeader =
    "model,run,tx_cm,ty_cm,tz_cm,rx_deg,ry_deg,rz_deg,converged,iterations,final_translation_mm,final_rotation_deg,"
    "decoded_initial,diverged,error_rise,max_error_ratio,off_centre_max,off_centre_total,stop_reason";

// Strict numbers for rows read back from a file (a merge reads shards it did not write).
bool whole_number(const std::string& t, long long lo, long long hi, long long& v) {
  if (t.empty() || t.size() > 19 || t.find_first_not_of("0123456789-") != std::string::npos) return false;
  char* end = nullptr;
  errno = 0;
  v = std::strtoll(t.c_str(), &end, 10);
  return errno == 0 && *end == '\0' && v >= lo && v <= hi;
}
bool finite_number(const std::string& t, double& v) {
  if (t.empty() || t.size() > 40 || t.find_first_not_of("0123456789+-.eE") != std::string::npos) return false;
  char* end = nullptr;
  v = std::strtod(t.c_str(), &end);
  return *end == '\0' && std::isfinite(v);
}

CampaignRow parse_row(const std::string& line, const std::string& where) {
  if (line.size() > 4096) throw std::invalid_argument(where + ": a row longer than 4096 characters");
  std::vector<std::string> f;
  std::size_t a = 0;
  for (int i = 0; i < 18; ++i) {
    const std::size_t b = line.find(',', a);
    if (b == std::string::npos) throw std::invalid_argument(where + ": a row with fewer than 19 fields");
    f.push_back(line.substr(a, b - a));
    a = b + 1;
  }
  CampaignRow r;
  r.line = line;
  r.model = f[0];
  long long v = 0;
  double d = 0;
  if (!whole_number(f[1], 0, 100000000, v)) throw std::invalid_argument(where + ": run '" + common::printable(f[1]) + "' is not a run index");
  r.run = static_cast<int>(v);
  for (int i = 2; i < 8; ++i)
    if (!finite_number(f[i], d)) throw std::invalid_argument(where + ": run " + f[1] + ": initial offset '" + common::printable(f[i]) + "' is not a finite number");
  if (f[8] != "0" && f[8] != "1") throw std::invalid_argument(where + ": run " + f[1] + ": converged '" + common::printable(f[8]) + "' is not 0 or 1");
  r.converged = f[8] == "1";
  if (!whole_number(f[9], 0, 100000000, v)) throw std::invalid_argument(where + ": run " + f[1] + ": iterations '" + common::printable(f[9]) + "' is not a count");
  r.iterations = static_cast<int>(v);
  if (!finite_number(f[10], r.translation_mm) || r.translation_mm < 0)
    throw std::invalid_argument(where + ": run " + f[1] + ": final_translation_mm '" + common::printable(f[10]) + "' is not a finite distance");
  if (!finite_number(f[11], r.rotation_deg) || r.rotation_deg < 0)
    throw std::invalid_argument(where + ": run " + f[1] + ": final_rotation_deg '" + common::printable(f[11]) + "' is not a finite angle");
  if (!whole_number(f[12], 0, 100000000, v)) throw std::invalid_argument(where + ": run " + f[1] + ": decoded_initial '" + common::printable(f[12]) + "' is not a count");
  if (f[13] != "0" && f[13] != "1") throw std::invalid_argument(where + ": run " + f[1] + ": diverged '" + common::printable(f[13]) + "' is not 0 or 1");
  r.diverged = f[13] == "1";
  if (!finite_number(f[14], r.error_rise) || r.error_rise < 0)
    throw std::invalid_argument(where + ": run " + f[1] + ": error_rise '" + common::printable(f[14]) + "' is not a finite rise");
  if (!finite_number(f[15], r.max_error_ratio) || r.max_error_ratio < 0)
    throw std::invalid_argument(where + ": run " + f[1] + ": max_error_ratio '" + common::printable(f[15]) + "' is not a finite ratio");
  if (!whole_number(f[16], 0, 100000000, r.off_centre_max))
    throw std::invalid_argument(where + ": run " + f[1] + ": off_centre_max '" + common::printable(f[16]) + "' is not a count");
  if (!whole_number(f[17], 0, 1000000000000, r.off_centre_total))
    throw std::invalid_argument(where + ": run " + f[1] + ": off_centre_total '" + common::printable(f[17]) + "' is not a count");
  r.stop_reason = line.substr(a);
  return r;
}

struct CampaignMeta {
  // every parameter that changes a run's outcome, and a hash of the scenario's content and of
  // every file it names: shards merge only when all of it is equal (issue 18, item 17)
  nlohmann::json parameters = nlohmann::json::object();
  std::string scenario_hash;
  std::string scenario, source, conditions = "none";
  std::uint64_t seed = 0;
  int runs = 0, max_iterations = 0, redrawn = 0, visible_desired = 0, shard_index = 1, shard_count = 1;
  std::vector<std::string> models;
  double scale = 1;
};

// The first field in which two shards' records differ, as "field: A against B"; "" when equal.
std::string campaign_difference(const CampaignMeta& a, const CampaignMeta& b) {
  const auto differ = [](const std::string& field, const nlohmann::json& x, const nlohmann::json& y) {
    return field + " is " + common::printable(x.dump(), 80) + ", the first shard's " + common::printable(y.dump(), 80);
  };
  if (a.scenario_hash != b.scenario_hash)
    return differ("scenario_sha (the scenario's content and its files)", b.scenario_hash, a.scenario_hash);
  const std::pair<const char*, std::pair<nlohmann::json, nlohmann::json>> fields[] = {
      {"scenario", {a.scenario, b.scenario}},         {"features", {a.source, b.source}},
      {"conditions", {a.conditions, b.conditions}},   {"seed", {a.seed, b.seed}},
      {"runs", {a.runs, b.runs}},                     {"max_iterations", {a.max_iterations, b.max_iterations}},
      {"models", {a.models, b.models}},               {"scale", {a.scale, b.scale}},
      {"shard count", {a.shard_count, b.shard_count}}, {"redrawn", {a.redrawn, b.redrawn}},
      {"visible_desired", {a.visible_desired, b.visible_desired}}};
  for (const auto& [name, v] : fields)
    if (v.first != v.second) return differ(name, v.second, v.first);
  for (const auto& [key, value] : a.parameters.items())
    if (!b.parameters.contains(key) || b.parameters.at(key) != value)
      return differ("parameters." + key, b.parameters.contains(key) ? b.parameters.at(key) : nlohmann::json(), value);
  for (const auto& [key, value] : b.parameters.items())
    if (!a.parameters.contains(key)) return differ("parameters." + key, value, nlohmann::json());
  return "";
}

CampaignMeta read_meta(const std::filesystem::path& file) {
  std::string text;
  try {
    text = common::read_regular_file(file, 1u << 20, "campaign description");
  } catch (const common::FileError& e) {
    throw std::invalid_argument(file.string() + ": cannot read (is this a campaign folder?): " + common::printable(e.what(), 120));
  }
  try {
    const nlohmann::json j = nlohmann::json::parse(text);
    CampaignMeta m;
    if (!j.contains("parameters") || !j.contains("scenario_sha"))
      throw std::invalid_argument("no parameters or scenario_sha (written before they were recorded: run it again)");
    m.parameters = j.at("parameters");
    if (!m.parameters.is_object() || m.parameters.size() > 64) throw std::invalid_argument("parameters is not a record");
    m.scenario_hash = j.at("scenario_sha").get<std::string>();
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
    if (m.runs < 1 || m.runs > 10000000 || m.shard_count < 1 || m.shard_count > m.runs || m.shard_index < 1 ||
        m.shard_index > m.shard_count || m.models.empty() || m.models.size() > 16 || m.max_iterations < 1 ||
        !std::isfinite(m.scale))
      throw std::invalid_argument("inconsistent values");
    for (const auto& model : m.models) control::parse_interaction_model(model);  // throws for an unknown one
    return m;
  } catch (const std::exception& e) {
    throw std::invalid_argument(file.string() + ": not a campaign description (" + common::printable(e.what()) + ")");
  }
}

std::vector<CampaignRow> read_rows(const std::filesystem::path& file) {
  std::string text;
  try {
    text = common::read_regular_file(file, 256u << 20, "campaign table");
  } catch (const common::FileError& e) {
    throw std::invalid_argument(e.what());
  }
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line) || line != kCsvHeader) throw std::invalid_argument(file.string() + ": not a campaign.csv");
  std::vector<CampaignRow> rows;
  while (std::getline(in, line))
    if (!line.empty()) rows.push_back(parse_row(line, file.string()));
  return rows;
}

// A shard's rows against its record: known models, runs of this shard, each once, no more
// iterations than the cap (a tampered or mixed-up table is refused, naming the row).
void check_shard_rows(const std::filesystem::path& file, const CampaignMeta& m, const std::vector<CampaignRow>& rows) {
  std::set<std::pair<std::string, int>> seen;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const CampaignRow& r = rows[i];
    const std::string at = file.string() + ": row " + std::to_string(i + 2) + ": ";
    if (std::find(m.models.begin(), m.models.end(), r.model) == m.models.end())
      throw std::invalid_argument(at + "model '" + common::printable(r.model, 40) + "' is not one of the campaign's");
    if (r.run >= m.runs) throw std::invalid_argument(at + "run " + std::to_string(r.run) + " is past the campaign's " + std::to_string(m.runs) + " runs");
    if (r.run % m.shard_count != m.shard_index - 1)
      throw std::invalid_argument(at + "run " + std::to_string(r.run) + " belongs to shard " +
                                  std::to_string(r.run % m.shard_count + 1) + "/" + std::to_string(m.shard_count) +
                                  ", not to this shard " + std::to_string(m.shard_index) + "/" + std::to_string(m.shard_count));
    if (!seen.insert({r.model, r.run}).second)
      throw std::invalid_argument(at + "run " + std::to_string(r.run) + " of " + r.model + " is given twice");
    if (r.iterations > m.max_iterations)
      throw std::invalid_argument(at + "iterations " + std::to_string(r.iterations) + " past the cap of " + std::to_string(m.max_iterations));
  }
  const std::size_t mine = static_cast<std::size_t>((m.runs - (m.shard_index - 1) + m.shard_count - 1) / m.shard_count);
  if (rows.size() != mine * m.models.size())
    throw std::invalid_argument(file.string() + ": " + std::to_string(rows.size()) + " rows, shard " +
                                std::to_string(m.shard_index) + "/" + std::to_string(m.shard_count) + " has " +
                                std::to_string(mine * m.models.size()) + " (a run missing: was the shard killed?)");
}

// a run "rose" when |e| passed this x its first value, or climbed in all (the sum of its rises,
// an oscillation's) at least its first value
constexpr double kRoseRatio = 2.0;

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
      // what stopped the run: its stop reason as the runner wrote it ("converged: ...",
      // "iteration cap (N) reached", "safe stop: ...", "diverging: ...")
      const std::string& why = r.stop_reason;
      const bool capped = why.find("iteration cap") != std::string::npos;
      m.capped += capped;
      m.safe_stops += why.find("safe stop") != std::string::npos;
      m.robot_stops += why.find("robot stop") != std::string::npos;
      m.rose += !r.diverged && (r.max_error_ratio > kRoseRatio || r.error_rise >= 1.0);
      rise.push_back(r.error_rise);
      m.off_centre_runs += r.off_centre_max > 0;
      m.off_centre_max = std::max(m.off_centre_max, r.off_centre_max);
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
  // every run is counted by what stopped it (converged, a diverging stop, the iteration cap, a
  // safe stop, the robot stopping by itself): the columns add up to the runs; "rose" counts the runs not stopped as diverging
  // whose |e| still rose: past twice its first value, or by its first value in all (issue 18,
  // item 6); medians of no run: -
  md << "| model | converged | diverging (stopped) | iteration cap | safe stop | robot stop (collision) | rose, "
        "not stopped | median iterations | median final error, converged runs (mm / deg) | worst final error, "
        "converged runs (mm / deg) | median rise of the error |\n"
     << "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const ModelStats& m : stats_of(meta.models, rows)) {
    char line[400];
    std::snprintf(line, sizeof line, "| %s | %d/%d (%.0f %%) | %d | %d | %d | %d | %d | %s | %s / %s | %s / %s | %s |\n",
                  m.model.c_str(), m.converged, m.runs, m.runs ? 100.0 * m.converged / m.runs : 0.0, m.diverged,
                  m.capped, m.safe_stops, m.robot_stops, m.rose, table_number(m.median_iterations, 0).c_str(),
                  table_number(m.median_translation_mm, 3).c_str(), table_number(m.median_rotation_deg, 4).c_str(),
                  table_number(m.worst_translation_mm, 3).c_str(), table_number(m.worst_rotation_deg, 4).c_str(),
                  table_number(m.median_error_rise, 3).c_str());
    md << line;
  }
  char note[260];
  std::snprintf(note, sizeof note,
                "\n%s, %d initial poses (seed %llu, %d draws redrawn for showing < 80 %% of the %d spots seen at "
                "the desired pose), %s features\n",
                meta.scenario.c_str(), meta.runs, static_cast<unsigned long long>(meta.seed), meta.redrawn,
                meta.visible_desired, meta.source.c_str());
  md << note;
  // what the decoded features put into the law that is not where its spot is (ideal ones are the truth)
  if (meta.source == "decoded")
    for (const ModelStats& m : stats_of(meta.models, rows))
      md << m.model << ": the law took a point off its spot's centre (over 2 px from it, or hidden: the simulator's "
            "truth) in " << m.off_centre_runs << " of " << m.runs << " runs, at most " << m.off_centre_max
         << " in one iteration\n";
  if (meta.conditions != "none") md << "errors and delays: " << meta.conditions << "\n";
  if (meta.shard_count > 1)
    md << "shard " << meta.shard_index << "/" << meta.shard_count << ": every " << meta.shard_count
       << "th initial pose from pose " << meta.shard_index - 1 << " (`cellsim campaign merge` combines the shards)\n";
  return md.str();
}

// the files a campaign writes at its end, checked before it runs: a refusal costs no run
void check_campaign_outputs(const std::filesystem::path& dir) {
  if (dir.empty()) return;
  for (const char* file : {"campaign.csv", "campaign.json", "summary.md"}) common::check_output_file(dir / file, "table");
}

void write_campaign(const std::filesystem::path& dir, const CampaignMeta& m, const std::vector<CampaignRow>& rows,
                    const std::string& md) {
  common::make_output_folder(dir);
  std::string csv = std::string(kCsvHeader) + "\n";
  for (const auto& r : rows) csv += r.line + "\n";
  common::write_output_file(dir / "campaign.csv", csv, "table");
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
  j["parameters"] = m.parameters;
  j["scenario_sha"] = m.scenario_hash;
  common::write_output_file(dir / "campaign.json", j.dump(1) + "\n", "summary");
  common::write_output_file(dir / "summary.md", md, "summary");
}

}  // namespace

std::string table_number(double v, int decimals) {
  if (!std::isfinite(v)) return "-";
  char b[48];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  return b;
}


std::string scenario_fingerprint(const sim::Scenario& sc) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  const auto add = [&](const std::string& bytes) {
    for (unsigned char c : bytes) h = (h ^ c) * 0x100000001b3ull;
    h = (h ^ 0xff) * 0x100000001b3ull;  // a separator: "ab"+"c" is not "a"+"bc"
  };
  const auto add_file = [&](const std::filesystem::path& f) {
    add(f.filename().string());
    try {
      add(common::read_regular_file(f, 256u << 20, "file"));
    } catch (const common::FileError&) {
      add("(unreadable)");
    }
  };
  add_file(sc.file);
  for (const auto& obj : sc.objects) add_file(obj.mesh);
  add_file(sc.projector.pattern);
  if (sc.robot.arm_enabled) {
    add_file(sc.robot.arm.urdf);
    // the link meshes the URDF names, in the order it names them
    const std::string urdf = sc.robot.model ? sc.robot.model->urdf : std::string();
    for (std::size_t at = 0; (at = urdf.find("filename=\"", at)) != std::string::npos;) {
      at += 10;
      const std::size_t end = urdf.find('"', at);
      if (end == std::string::npos) break;
      std::filesystem::path mesh(urdf.substr(at, end - at));
      if (mesh.is_relative()) mesh = sc.robot.arm.urdf.parent_path() / mesh;
      add_file(mesh);
      at = end;
    }
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}

namespace {

struct InitialPoses {
  std::vector<std::array<double, 6>> offsets;  // x y z (cm), rx ry rz (deg) per run
  int redrawn = 0;
  int visible_desired = 0;  // spots the camera sees at the desired pose
};

// The same initial poses for every model. A draw from which the camera does not see at least
// 80 % of the spots it sees at the desired pose, or that the arm cannot reach, is drawn again:
// the campaign compares control laws, not whether the object is in view.
InitialPoses draw_initial_poses(const sim::Cell& cell, const CampaignOptions& o) {
  const sim::Scenario& sc = cell.scenario;
  const auto visible = [&](const Eigen::Isometry3d& wTc) {
    int n = 0;
    for (const auto& t : sim::compute_truth(cell, wTc)) n += t.visible;
    return n;
  };
  InitialPoses poses;
  poses.visible_desired = visible(sc.world_T_desired);
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
  poses.offsets.resize(static_cast<std::size_t>(o.runs));
  for (auto& off : poses.offsets) {
    for (int attempt = 0;; ++attempt) {
      for (int i = 0; i < 6; ++i) {
        const double range =
            o.scale * std::max(2.0, std::abs(i < 3 ? sc.initial_translation_cm[i] : sc.initial_rotation_deg[i - 3]));
        off[i] = std::uniform_real_distribution<double>(-range, range)(rng);
      }
      const auto wTc = sim::offset_pose(sc.world_T_desired, {off[0], off[1], off[2]}, {off[3], off[4], off[5]},
                                        sc.offset_frame_rotation_deg);
      if ((visible(wTc) >= 0.8 * poses.visible_desired && reachable(wTc)) || attempt >= 1000) break;
      ++poses.redrawn;
    }
  }
  return poses;
}

struct CampaignJob {
  std::size_t model;
  int run;
  ExperimentResult result;
};

// One run of the campaign: its model, its initial pose, its own noise seed.
ExperimentResult run_job(const sim::Cell& cell, const CampaignOptions& o, const CampaignJob& job,
                         const std::array<double, 6>& off) {
  const sim::Scenario& sc = cell.scenario;
  ExperimentOptions e;
  e.servo = o.base;
  e.servo.law.model = o.models[job.model];
  e.source = o.source;
  e.max_iterations = o.max_iterations;
  e.initial = sim::offset_pose(sc.world_T_desired, {off[0], off[1], off[2]}, {off[3], off[4], off[5]},
                               sc.offset_frame_rotation_deg);
  e.noise_seed = o.seed * 1000003 + static_cast<std::uint64_t>(job.run);
  e.errors = o.errors;
  e.latency = o.latency;
  e.servo.divergence_ratio = o.divergence_ratio;
  e.outlier_fraction = o.outlier_fraction;
  e.loss_fraction = o.loss_fraction;
  e.white_frame = o.white_frame;
  e.white_frame_lead = o.white_frame_lead;
  e.render_threads = 1;  // one thread per run: the runs share the cores out among themselves
  ExperimentResult r = run_experiment(cell, e);
  r.trace.clear();  // keep memory flat: only the outcome matters here
  return r;
}

// The jobs on `threads` threads, one run per thread at a time, with the time left on stderr.
void run_jobs(const sim::Cell& cell, const CampaignOptions& o, const InitialPoses& poses,
              std::vector<CampaignJob>& jobs) {
  std::atomic<std::size_t> next{0}, done{0};
  std::mutex io;
  common::Progress progress("campaign " + cell.scenario.name, jobs.size(), "runs");
  const auto work = [&] {
    for (std::size_t j; (j = next++) < jobs.size();) {
      CampaignJob& job = jobs[j];
      job.result = run_job(cell, o, job, poses.offsets[static_cast<std::size_t>(job.run)]);
      if (common::verbose()) {
        std::lock_guard<std::mutex> lock(io);
        const ExperimentResult& r = job.result;
        std::fprintf(stderr, "campaign %s: run %d, %s: %s after %d iterations, %.3f mm, %.4f deg\n",
                     cell.scenario.name.c_str(), job.run, control::to_string(o.models[job.model]).c_str(),
                     r.converged ? "converged" : r.stop_reason.c_str(), r.iterations,
                     1e3 * r.final_translation_error_m, r.final_rotation_error_deg);
      }
      progress.at(++done);
    }
  };
  // a run that throws stops the others from taking a job, and is rethrown here
  common::run_workers(o.threads, work, [&] { next = jobs.size(); });
}

// campaign.csv's rows, by model, written and read back as the file has them
std::vector<CampaignRow> rows_of(const CampaignOptions& o, const InitialPoses& poses,
                                 const std::vector<CampaignJob>& jobs) {
  std::vector<CampaignRow> rows;
  for (std::size_t m = 0; m < o.models.size(); ++m)
    for (const CampaignJob& job : jobs) {
      if (job.model != m) continue;
      const auto& r = job.result;
      std::ostringstream line;
      line << std::setprecision(17) << control::to_string(o.models[m]) << ',' << job.run;
      for (double x : poses.offsets[static_cast<std::size_t>(job.run)]) line << ',' << x;
      line << ',' << r.converged << ',' << r.iterations << ',' << 1e3 * r.final_translation_error_m << ','
           << r.final_rotation_error_deg << ',' << r.decoded_initial << ',' << r.diverged << ',' << r.error_rise << ','
           << r.max_error_ratio << ',' << r.off_centre_max << ',' << r.off_centre_total << ",\"" << r.stop_reason << "\"";
      rows.push_back(parse_row(line.str(), "campaign"));
    }
  return rows;
}

CampaignMeta meta_of(const sim::Scenario& sc, const CampaignOptions& o, const InitialPoses& poses) {
  CampaignMeta meta;
  meta.scenario = sc.name;
  meta.seed = o.seed;
  meta.runs = o.runs;
  for (const auto m : o.models) meta.models.push_back(control::to_string(m));
  meta.source = to_string(o.source);
  meta.scale = o.scale;
  meta.conditions = sim::describe(o.errors.value_or(sc.errors), o.latency.value_or(sc.latency));
  meta.max_iterations = o.max_iterations;
  meta.redrawn = poses.redrawn;
  meta.visible_desired = poses.visible_desired;
  meta.shard_index = o.shard_index;
  meta.shard_count = o.shard_count;
  meta.scenario_hash = scenario_fingerprint(sc);
  const control::ControlLawOptions& law = o.base.law;
  meta.parameters = {{"gain", {law.gain.lambda_zero, law.gain.lambda_inf, law.gain.slope_zero}},
                     {"z_hat_m", law.z_hat_m},
                     {"points", o.base.points},
                     {"interior_points", o.base.interior_points},
                     {"taught_points", o.base.taught_points},
                     {"divergence_ratio", o.divergence_ratio},
                     {"convergence_translation_m", law.convergence_translation_m},
                     {"convergence_rotation_rad", law.convergence_rotation_rad},
                     {"max_linear_mps", law.max_linear_mps},
                     {"max_angular_radps", law.max_angular_radps},
                     {"min_points", law.min_points},
                     {"epipolar", o.base.decoder.epipolar.enabled},
                     {"fitted_lines", o.base.decoder.epipolar.fitted_lines},
                     {"robust", control::to_string(law.robust)},
                     {"visual_features", control::to_string(law.features)},
                     {"outliers", o.outlier_fraction},
                     {"losses", o.loss_fraction},
                     {"white_frame", o.white_frame},
                     {"white_frame_lead", o.white_frame_lead}};
  return meta;
}

}  // namespace

std::string run_campaign(const sim::Cell& cell, const CampaignOptions& o) {
  loop::check_injections(o.source, o.outlier_fraction, o.loss_fraction);  // before a folder or a thread
  check_campaign_outputs(o.out_dir);
  const InitialPoses poses = draw_initial_poses(cell, o);
  std::vector<CampaignJob> jobs;
  // a shard runs every N-th initial pose: the draws above are the same for every shard
  for (std::size_t m = 0; m < o.models.size(); ++m)
    for (int r = 0; r < o.runs; ++r)
      if (r % o.shard_count == o.shard_index - 1) jobs.push_back({m, r, {}});
  run_jobs(cell, o, poses, jobs);
  const std::vector<CampaignRow> rows = rows_of(o, poses, jobs);
  const CampaignMeta meta = meta_of(cell.scenario, o, poses);
  const std::string md = summarize(meta, rows);
  if (!o.out_dir.empty()) write_campaign(o.out_dir, meta, rows, md);
  return md;
}

std::string merge_campaigns(const std::vector<std::filesystem::path>& dirs, const std::filesystem::path& out_dir) {
  check_campaign_outputs(out_dir);
  if (dirs.empty()) throw std::invalid_argument("campaign merge: no shard folders given");
  std::optional<CampaignMeta> first;
  std::set<int> shards;
  std::vector<CampaignRow> rows;
  for (const auto& dir : dirs) {
    const CampaignMeta meta = read_meta(dir / "campaign.json");
    if (!first) {
      first = meta;
    } else if (const std::string d = campaign_difference(*first, meta); !d.empty()) {
      throw std::invalid_argument((dir / "campaign.json").string() + ": another campaign than the first folder's (" +
                                  dirs.front().string() + "): " + d);
    }
    if (!shards.insert(meta.shard_index).second)
      throw std::invalid_argument((dir / "campaign.json").string() + ": shard " + std::to_string(meta.shard_index) +
                                  " given twice");
    auto shard_rows = read_rows(dir / "campaign.csv");
    check_shard_rows(dir / "campaign.csv", meta, shard_rows);
    for (auto& r : shard_rows) rows.push_back(std::move(r));
  }
  if (static_cast<int>(shards.size()) != first->shard_count) {
    std::string missing;
    for (int i = 1; i <= first->shard_count && missing.size() < 200; ++i)
      if (!shards.count(i)) missing += (missing.empty() ? "" : ", ") + std::to_string(i) + "/" + std::to_string(first->shard_count);
    throw std::invalid_argument("campaign merge: " + std::to_string(shards.size()) + " of the " +
                                std::to_string(first->shard_count) + " shards given; missing: shard " + missing);
  }
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

std::array<double, 6> draw_initial_offset(const sim::Cell& cell, std::uint64_t seed, double scale) {
  CampaignOptions o;
  o.runs = 1;
  o.seed = seed;
  o.scale = scale;
  return draw_initial_poses(cell, o).offsets[0];
}

}  // namespace experiment
