#include "sim/app/experiment.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "sim/robot/robot.hpp"

namespace cellsim {

namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

// The spots the controller sees: decoded from the rendered image, or the truth's visible ones.
std::vector<servo::ImageSpot> observe(const sim::Cell& cell, const servo::ServoPipeline& pipeline, FeatureSource src,
                                      const Eigen::Isometry3d& wTc, std::uint64_t seed, sim::RenderScratch& scratch,
                                      int* detected) {
  if (src == FeatureSource::kIdeal) {
    std::vector<servo::ImageSpot> spots;
    for (const auto& t : sim::compute_truth(cell, wTc))
      if (t.visible) spots.push_back({t.row, t.col, t.uv.x(), t.uv.y()});
    if (detected) *detected = 0;
    return spots;
  }
  return pipeline.locate(sim::render_image(cell, wTc, seed, &scratch), detected);
}

}  // namespace

FeatureSource parse_feature_source(const std::string& name) {
  if (name == "decoded") return FeatureSource::kDecoded;
  if (name == "ideal") return FeatureSource::kIdeal;
  throw std::invalid_argument("feature source '" + name + "': expected decoded or ideal");
}

std::string to_string(FeatureSource s) { return s == FeatureSource::kIdeal ? "ideal" : "decoded"; }

servo::ServoConfig servo_config_for(const sim::Cell& cell) {
  servo::ServoConfig c;
  const sim::CameraSpec& cam = cell.scenario.camera;
  c.camera = {cam.intrinsics.fx, cam.intrinsics.fy, cam.intrinsics.cx, cam.intrinsics.cy, cam.distortion};
  const sim::ProjectorSpec& p = cell.projector->spec();
  control::ProjectorModel pm;
  pm.fx = p.intrinsics.fx;
  pm.fy = p.intrinsics.fy;
  pm.cx = p.intrinsics.cx;
  pm.cy = p.intrinsics.cy;
  pm.spot_pitch_px = p.spot_pitch_px;
  pm.rows = cell.projector->pattern().rows;
  pm.cols = cell.projector->pattern().cols;
  pm.world_T_projector = p.world_T_projector;
  c.projector = pm;
  c.law.max_linear_mps = cell.scenario.robot.max_linear_mps;
  c.law.max_angular_radps = cell.scenario.robot.max_angular_radps;
  return c;
}

ExperimentResult run_experiment(const sim::Cell& cell, const ExperimentOptions& o) {
  const sim::Scenario& sc = cell.scenario;
  const std::uint64_t seed = o.noise_seed ? o.noise_seed : sc.seed;
  servo::ServoPipeline pipeline(pattern::WindowTable(cell.projector->pattern(), {3, 3}), o.servo);
  sim::RenderScratch scratch;
  ExperimentResult res;

  // teach by showing: the robot at the desired pose, s* from what the camera sees there
  sim::FreeFlyingCamera robot(sc.world_T_desired, sc.robot.max_linear_mps, sc.robot.max_angular_radps);
  std::uint64_t frame = 0;
  const auto taught = observe(cell, pipeline, o.source, robot.world_T_camera(), sim::frame_seed(seed, frame++), scratch,
                              nullptr);
  res.decoded_desired = pipeline.teach(taught, robot.world_T_camera());

  robot.reset(o.initial.value_or(sc.world_T_initial()));
  std::ofstream trace, features;
  if (!o.out_dir.empty()) {
    std::filesystem::create_directories(o.out_dir);
    trace.open(o.out_dir / "trace.csv");
    if (!trace) throw std::runtime_error((o.out_dir / "trace.csv").string() + ": cannot write");
    trace << "# scenario " << sc.name << ", model " << control::to_string(o.servo.law.model) << ", features "
          << to_string(o.source) << (o.source == FeatureSource::kIdeal ? " (simulator truth, not decoded)" : "")
          << "\n";
    trace << "t,vx,vy,vz,wx,wy,wz,error_norm,decoded,matched,translation_error_m,rotation_error_deg\n";
    trace << std::setprecision(9);
    if (o.write_features) features.open(o.out_dir / "features.jsonl");
  }

  for (int k = 0; k < o.max_iterations; ++k) {
    const Eigen::Isometry3d wTc = robot.world_T_camera();
    const auto spots = observe(cell, pipeline, o.source, wTc, sim::frame_seed(seed, frame++), scratch, nullptr);
    if (k == 0) res.decoded_initial = static_cast<int>(spots.size());
    const servo::StepResult step = pipeline.step(spots, wTc);

    IterationRecord rec;
    rec.t_s = k * sc.dt_s;
    rec.twist = step.control.twist;
    rec.error_norm = step.control.error_norm;
    rec.feature_rms = step.control.feature_rms;
    rec.decoded = step.decoded;
    rec.matched = static_cast<int>(step.matched.size());
    rec.translation_error_m = sim::translation_error(wTc, sc.world_T_desired);
    rec.rotation_error_deg = sim::rotation_error(wTc, sc.world_T_desired) * kRadToDeg;
    res.trace.push_back(rec);
    res.iterations = k + 1;
    if (trace.is_open()) {
      trace << rec.t_s;
      for (int i = 0; i < 6; ++i) trace << ',' << rec.twist[i];
      trace << ',' << rec.error_norm << ',' << rec.decoded << ',' << rec.matched << ',' << rec.translation_error_m << ','
            << rec.rotation_error_deg << '\n';
    }
    if (features.is_open()) {
      nlohmann::json j;
      j["k"] = k;
      j["model"] = control::to_string(o.servo.law.model);
      j["features"] = to_string(o.source);
      j["gain"] = step.control.gain;
      j["points"] = nlohmann::json::array();
      for (std::size_t i = 0; i < step.matched.size(); ++i) {
        const auto& m = step.matched[i];
        nlohmann::json p{{"row", m.row}, {"col", m.col}, {"x", m.x}, {"y", m.y}, {"x_star", m.x_star}, {"y_star", m.y_star}};
        const double z = i < step.control.z_model.size() ? step.control.z_model[i] : std::nan("");
        p["z_model"] = std::isfinite(z) ? nlohmann::json(z) : nlohmann::json(nullptr);
        j["points"].push_back(p);
      }
      j["v"] = std::vector<double>(step.control.twist.data(), step.control.twist.data() + 6);
      features << j.dump() << '\n';
    }
    if (step.control.status == control::ControlStatus::kConverged) {
      res.converged = true;
      res.stop_reason = "converged: " + step.control.reason;
      break;
    }
    if (step.control.status != control::ControlStatus::kServoing) {
      res.stop_reason = "safe stop: " + step.control.reason;
      break;
    }
    robot.apply_twist(step.control.twist, sc.dt_s);
  }
  if (res.stop_reason.empty()) res.stop_reason = "iteration cap (" + std::to_string(o.max_iterations) + ") reached";
  res.final_translation_error_m = sim::translation_error(robot.world_T_camera(), sc.world_T_desired);
  res.final_rotation_error_deg = sim::rotation_error(robot.world_T_camera(), sc.world_T_desired) * kRadToDeg;
  return res;
}

bool plot_experiment(const std::filesystem::path& dir, const std::string& title) {
  const std::filesystem::path script = std::filesystem::path(CELL_SOURCE_DIR) / "bin" / "plot_trace.py";
  const std::string cmd = "/usr/bin/python3 '" + script.string() + "' '" + dir.string() + "' --title '" + title + "'";
  if (std::system(cmd.c_str()) != 0) {
    std::fprintf(stderr, "cellsim: plotting failed (%s); the trace is in %s\n", cmd.c_str(), dir.c_str());
    return false;
  }
  return true;
}

}  // namespace cellsim
