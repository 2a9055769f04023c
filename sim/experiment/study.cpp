#include "common/progress.hpp"
#include "sim/cell/build_cell.hpp"
#include "sim/experiment/study.hpp"

#include "common/decimal_number.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "common/output_file.hpp"
#include "common/strict_yaml.hpp"
#include "sim/render/cell.hpp"

namespace experiment {

namespace {

constexpr std::size_t kMaxAxisValues = 64;

bool is_object_scale(const std::string& name) {
  return name == "object_scale_x" || name == "object_scale_y" || name == "object_scale_z";
}

// axes that change the world: each point needs a cell of its own
bool reshapes_world(const std::string& name) { return is_object_scale(name) || name == "object_yaw_deg"; }

bool is_error(const std::string& name) {
  const auto n = sim::error_names();
  return std::find(n.begin(), n.end(), name) != n.end();
}

bool is_latency(const std::string& name) {
  const auto n = sim::latency_names();
  return std::find(n.begin(), n.end(), name) != n.end();
}

// An axis that switches an option: 1 on, 0 off (`off` says what 0 means); anything else refused.
bool switched_on(const std::string& name, double v, const char* off) {
  if (v != 0 && v != 1) {
    char m[160];
    std::snprintf(m, sizeof m, "study axis %s: %.6g is neither 0 (%s) nor 1", name.c_str(), v, off);
    throw std::invalid_argument(m);
  }
  return v != 0;
}

void check_within(const std::string& name, double v, double lo, double hi) {
  if (!(v >= lo && v <= hi)) {
    char m[160];
    std::snprintf(m, sizeof m, "study axis %s: %.6g is outside [%g, %g]", name.c_str(), v, lo, hi);
    throw std::invalid_argument(m);
  }
}

// The axes that switch the servo's options and the white frame's; false for another axis.
bool apply_switch(const std::string& name, double v, CampaignOptions& c) {
  if (name == "interior_points") {
    // 1: the law on the interior of the matched spots (ServoConfig::interior_points), 0: on all
    c.base.interior_points = switched_on(name, v, "all matched spots");
  } else if (name == "taught_points") {
    // 1: each id held to the point its spot lit at teaching (ServoConfig::taught_points)
    c.base.taught_points = switched_on(name, v, "not held");
  } else if (name == "white_frame") {
    // 1: the white reference frame beside each pattern frame (ExperimentOptions::white_frame)
    c.white_frame = switched_on(name, v, "the pattern frame alone");
    if (c.white_frame && loop::from_truth_alone(c.source))
      throw std::invalid_argument("study axis white_frame: needs --features decoded or decoded-ids");
  } else if (name == "white_frame_lead") {
    // the share of a frame period the white frame is taken before its pattern frame (the camera
    // moving between them; ExperimentOptions::white_frame_lead)
    check_within(name, v, 0, 1);
    if (!c.white_frame) throw std::invalid_argument("study axis white_frame_lead: needs --white-frame");
    c.white_frame_lead = v;
  } else {
    return false;
  }
  return true;
}

// Sets one axis value; throws std::invalid_argument when it is out of range.
void apply(const std::string& name, double v, sim::Scenario& s, CampaignOptions& c) {
  const auto within = [&](double lo, double hi) { check_within(name, v, lo, hi); };
  if (apply_switch(name, v, c)) return;
  if (name == "z_hat") {
    within(0.01, 100);
    c.base.law.z_hat_m = v;
  } else if (name == "gain") {
    within(1e-6, 100);
    c.base.law.gain = control::Gain{v, v, 0};
  } else if (name == "offset_scale") {
    // the size of the initial offsets: the share that converges as it grows is the
    // convergence domain (issue 19)
    within(0, 100);
    c.scale = v;
  } else if (name == "visual_features") {
    // what the law servoes on (issue 44), by its index: 0 points, 1 moments, 2 surface, 3
    // plane; the axis is written with the names (visual_features=points,surface)
    within(0, 3);
    if (v != std::floor(v)) within(1, 0);  // not an index
    c.base.law.features = static_cast<control::VisualFeatures>(static_cast<int>(v));
  } else if (name == "losses") {
    // the fraction of the decoded spots dropped at every frame (decoding losses, issue 44)
    within(0, 0.9);
    c.loss_fraction = v;
  } else if (name == "outliers") {
    // the fraction of the spots whose ids are swapped at every frame
    within(0, 0.5);
    c.outlier_fraction = v;
  } else if (name == "error_scale") {
    // every calibration error given (scenario or --error) times this factor
    within(0, 1000);
    sim::CalibrationErrors e = c.errors.value_or(s.errors);
    for (const auto& [n, magnitude] : sim::error_values(e))
      if (magnitude != 0) sim::set_error(e, n, magnitude * v);
    c.errors = e;
  } else if (is_object_scale(name)) {
    within(0.01, 100);
    for (auto& o : s.objects) o.scale[name.back() - 'x'] = v;
  } else if (name == "object_yaw_deg") {
    // every object turned about the vertical through its origin: a tilted plane shows the
    // camera a depth spread that grows with the angle
    within(-89, 89);
    for (auto& o : s.objects) {
      const Eigen::Vector3d p = o.world_T_object.translation();
      o.world_T_object.linear() = Eigen::AngleAxisd(v * 3.14159265358979323846 / 180, Eigen::Vector3d::UnitZ()) *
                                  o.world_T_object.linear();
      o.world_T_object.translation() = p;
    }
  } else if (is_error(name)) {
    if (!c.errors) c.errors = s.errors;
    sim::set_error(*c.errors, name, v);
  } else if (is_latency(name)) {
    if (!c.latency) c.latency = s.latency;
    sim::set_latency(*c.latency, name, v);
  } else {
    std::string known;
    for (const auto& n : study_axis_names()) {
      if (!known.empty()) known += ", ";
      known += n;
    }
    throw std::invalid_argument("study axis '" + common::printable(name.substr(0, 60)) + "': unknown (known: " + known +
                                ")");
  }
}

std::string label(const std::vector<StudyAxis>& axes, const std::vector<double>& values) {
  std::ostringstream l;
  l << std::setprecision(6);
  for (std::size_t i = 0; i < axes.size(); ++i) {
    l << (i ? "," : "") << axes[i].name << '=';
    if (axes[i].name == "visual_features")
      l << control::to_string(static_cast<control::VisualFeatures>(static_cast<int>(values[i])));
    else
      l << values[i];
  }
  return l.str();
}

// max - min of the depths of the spots seen at the desired pose (the spread the models face)
double depth_spread(const sim::Cell& cell) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const auto& t : sim::compute_truth(cell, cell.scenario.world_T_desired))
    if (t.visible) lo = std::min(lo, t.depth_m), hi = std::max(hi, t.depth_m);
  return hi >= lo ? hi - lo : 0.0;
}

}  // namespace

std::vector<std::string> study_axis_names() {
  std::vector<std::string> n{"z_hat",          "gain",           "object_scale_x", "object_scale_y", "object_scale_z",
                             "object_yaw_deg", "error_scale",    "offset_scale",   "outliers", "losses", "visual_features",
                             "interior_points", "taught_points", "white_frame", "white_frame_lead"};
  for (const auto& e : sim::error_names()) n.push_back(e);
  for (const auto& l : sim::latency_names()) n.push_back(l);
  return n;
}

StudyAxis parse_study_axis(const std::string& spec) {
  const std::size_t eq = spec.find('=');
  if (spec.size() > 2000 || eq == std::string::npos)
    throw std::invalid_argument("study axis '" + common::printable(spec.substr(0, 60)) +
                                "': expected NAME=V1,V2,... (e.g. z_hat=0.3,0.6,0.9)");
  StudyAxis a;
  a.name = spec.substr(0, eq);
  std::stringstream list(spec.substr(eq + 1));
  for (std::string item; std::getline(list, item, ',');) {
    std::optional<double> parsed = common::decimal_number(item);  // "0x10" is not 16
    if (a.name == "visual_features") {  // by name: points, moments, surface, plane
      try {
        parsed = static_cast<double>(control::parse_visual_features(item));
      } catch (const std::invalid_argument& e) {
        throw std::invalid_argument("study axis visual_features: " + std::string(e.what()));
      }
    }
    const double v = parsed.value_or(0);
    if (!parsed)
      throw std::invalid_argument("study axis " + common::printable(a.name.substr(0, 60)) + ": '" +
                                  common::printable(item.substr(0, 40)) + "' is not a number");
    if (std::find(a.values.begin(), a.values.end(), v) != a.values.end())
      throw std::invalid_argument("study axis " + common::printable(a.name.substr(0, 60)) + ": value '" +
                                  common::printable(item.substr(0, 40)) + "' given twice");
    a.values.push_back(v);
    if (a.values.size() > kMaxAxisValues)
      throw std::invalid_argument("study axis " + common::printable(a.name.substr(0, 60)) + ": more than " +
                                  std::to_string(kMaxAxisValues) + " values");
  }
  if (a.values.empty()) throw std::invalid_argument("study axis " + common::printable(a.name.substr(0, 60)) + ": no values");
  // every value checked now, not when its campaign's turn comes (its range here; against the
  // study's own campaign, which may lack what a value needs, in check_study)
  for (double v : a.values) {
    sim::Scenario s;
    CampaignOptions c;
    c.white_frame = true;
    apply(a.name, v, s, c);
  }
  return a;
}

namespace {
// The study's axes and folder, and every value checked against its campaign too (the white
// frame needs decoded features), before a folder is made or a campaign runs.
void check_study(const sim::ResolvedScenario& scenario, const StudyOptions& o) {
  if (o.axes.empty() || o.axes.size() > 2) throw std::invalid_argument("study: give one or two --axis");
  if (o.out_dir.empty()) throw std::invalid_argument("study: -o,--output FOLDER is required");
  for (const StudyAxis& a : o.axes)
    for (double v : a.values) {
      sim::Scenario s = scenario;
      CampaignOptions c = o.campaign;
      apply(a.name, v, s, c);
      loop::check_injections(c.source, c.outlier_fraction, c.loss_fraction);
    }
}

// the study's points: every value of the first axis, by every value of the second if there is one
std::vector<std::vector<double>> study_grid(const StudyOptions& o) {
  std::vector<std::vector<double>> grid;
  for (double a : o.axes[0].values) {
    if (o.axes.size() == 1) {
      grid.push_back({a});
    } else {
      for (double b : o.axes[1].values) grid.push_back({a, b});
    }
  }
  return grid;
}

}  // namespace

std::string run_study(const sim::ResolvedScenario& scenario, const StudyOptions& o) {
  check_study(scenario, o);
  common::make_output_folder(o.out_dir);
  for (const char* file : {"summary.md", "study.json"}) common::check_output_file(o.out_dir / file, "summary");
  const std::vector<std::vector<double>> grid = study_grid(o);
  const bool reshapes = std::any_of(o.axes.begin(), o.axes.end(), [](const StudyAxis& a) { return reshapes_world(a.name); });
  const std::unique_ptr<sim::Cell> shared = reshapes ? nullptr : sim::build_cell(scenario);

  common::OutputStream csv;
  csv.open(o.out_dir / "study.csv", "table");
  for (const auto& a : o.axes) csv << a.name << ',';
  csv << "depth_spread_m,model,runs,converged,diverged,capped,safe_stops,robot_stops,rose,converged_pct,median_iterations,"
         "median_translation_mm,median_rotation_deg,median_error_rise,folder\n"
      << std::setprecision(10);
  std::ostringstream md;
  md << "| ";
  for (const auto& a : o.axes) md << a.name << " | ";
  // every run counted by what stopped it; "rose": not stopped as diverging, yet |e| rose (past
  // twice its first value, or by it in all): a study without --divergence-ratio counts its
  // runaways and oscillations there
  md << "depth spread (mm) | model | converged | diverging (stopped) | iteration cap | safe stop | robot stop "
        "(collision) | rose, not stopped | median iterations | median final error (mm / deg) | median rise of the "
        "error |\n|";
  for (std::size_t i = 0; i < o.axes.size() + 11; ++i) md << "---|";
  md << "\n";

  for (std::size_t g = 0; g < grid.size(); ++g) {
    sim::Scenario s = scenario;
    CampaignOptions c = o.campaign;
    for (std::size_t i = 0; i < o.axes.size(); ++i) apply(o.axes[i].name, grid[g][i], s, c);
    const std::string name = label(o.axes, grid[g]);
    c.out_dir = o.out_dir / name;
    if (!common::quiet())
      std::fprintf(stderr, "study %s: point %zu/%zu, %s\n", scenario.name.c_str(), g + 1, grid.size(), name.c_str());
    const std::unique_ptr<sim::Cell> own = reshapes ? sim::build_cell(sim::resolve(s)) : nullptr;
    const sim::Cell& cell = reshapes ? *own : *shared;
    run_campaign(cell, c);
    const double spread = depth_spread(cell);
    for (const ModelStats& m : campaign_stats(c.out_dir)) {
      for (double v : grid[g]) csv << v << ',';
      csv << spread << ',' << m.model << ',' << m.runs << ',' << m.converged << ',' << m.diverged << ',' << m.capped
          << ',' << m.safe_stops << ',' << m.robot_stops << ',' << m.rose << ','
          << (m.runs ? 100.0 * m.converged / m.runs : 0.0) << ',' << m.median_iterations << ','
          << m.median_translation_mm << ',' << m.median_rotation_deg << ',' << m.median_error_rise << ",\"" << name
          << "\"\n";
      char row[400];
      std::snprintf(row, sizeof row, "| %.1f | %s | %d/%d | %d | %d | %d | %d | %d | %s | %s / %s | %s |\n",
                    1e3 * spread, m.model.c_str(), m.converged, m.runs, m.diverged, m.capped, m.safe_stops,
                    m.robot_stops, m.rose,
                    table_number(m.median_iterations, 0).c_str(), table_number(m.median_translation_mm, 3).c_str(),
                    table_number(m.median_rotation_deg, 4).c_str(), table_number(m.median_error_rise, 3).c_str());
      md << "| ";
      for (std::size_t i = 0; i < grid[g].size(); ++i) {
        if (o.axes[i].name == "visual_features")
          md << control::to_string(static_cast<control::VisualFeatures>(static_cast<int>(grid[g][i]))) << " | ";
        else
          md << grid[g][i] << " | ";
      }
      md << (row + 2);
    }
  }
  csv.close();
  md << "\n" << scenario.name << ", " << o.campaign.runs << " initial poses per point (seed " << o.campaign.seed
     << "), " << to_string(o.campaign.source) << " features; one campaign folder per point\n";
  common::write_output_file(o.out_dir / "summary.md", md.str(), "summary");
  nlohmann::json j;
  j["scenario"] = scenario.name;
  j["runs"] = o.campaign.runs;
  j["seed"] = o.campaign.seed;
  j["features"] = to_string(o.campaign.source);
  for (const auto& a : o.axes) j["axes"].push_back({{"name", a.name}, {"values", a.values}});
  common::write_output_file(o.out_dir / "study.json", j.dump(1) + "\n", "summary");
  return md.str();
}

bool plot_study(const std::filesystem::path& dir, const std::string& title) {
  return run_plot_script("plot_study.py", dir, title);
}

}  // namespace experiment
