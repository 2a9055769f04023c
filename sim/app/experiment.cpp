#include "sim/app/experiment.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "sim/cell/trace.hpp"
#include "sim/robot/robot.hpp"

namespace cellsim {

namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

// The spots the controller sees: decoded from the rendered image, or the truth's visible ones.
std::vector<servo::ImageSpot> observe(const sim::Cell& cell, const servo::ServoPipeline& pipeline, FeatureSource src,
                                      const Eigen::Isometry3d& wTc, const sim::LinkPoses& links, std::uint64_t seed,
                                      sim::RenderScratch& scratch, int* detected) {
  if (src == FeatureSource::kIdeal) {
    std::vector<servo::ImageSpot> spots;
    for (const auto& t : sim::compute_truth(cell, wTc, &links))
      if (t.visible) spots.push_back({t.row, t.col, t.uv.x(), t.uv.y()});
    if (detected) *detected = 0;
    return spots;
  }
  return pipeline.locate(sim::render_image(cell, wTc, seed, &scratch, nullptr, &links), wTc, detected);
}

}  // namespace

FeatureSource parse_feature_source(const std::string& name) {
  if (name == "decoded") return FeatureSource::kDecoded;
  if (name == "ideal") return FeatureSource::kIdeal;
  throw std::invalid_argument("feature source '" + name + "': expected decoded or ideal");
}

std::string to_string(FeatureSource s) { return s == FeatureSource::kIdeal ? "ideal" : "decoded"; }

control::CameraIntrinsics camera_intrinsics_of(const sim::Cell& cell) {
  const sim::CameraSpec& cam = cell.scenario.camera;
  return {cam.intrinsics.fx, cam.intrinsics.fy, cam.intrinsics.cx, cam.intrinsics.cy, cam.distortion};
}

control::ProjectorModel projector_model_of(const sim::Cell& cell) {
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
  return pm;
}

servo::ServoConfig servo_config_for(const sim::Cell& cell) {
  servo::ServoConfig c;
  c.camera = camera_intrinsics_of(cell);
  c.projector = projector_model_of(cell);
  // the projector's calibration is there for triangulation; decoding with it is an option
  // (`cellsim experiment --epipolar`), so runs compare with a servo started without --projector
  c.decoder.epipolar.enabled = false;
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
  const std::unique_ptr<sim::Robot> robot_owner = sim::make_robot(cell);
  sim::Robot& robot = *robot_owner;
  std::uint64_t frame = 0;
  const auto taught = observe(cell, pipeline, o.source, robot.world_T_camera(), robot.world_T_links(),
                              sim::frame_seed(seed, frame++), scratch, nullptr);
  res.decoded_desired = pipeline.teach(taught, robot.world_T_camera());

  try {
    robot.reset(o.initial.value_or(sc.world_T_initial()));
  } catch (const std::invalid_argument& e) {
    res.stop_reason = std::string("initial pose refused: ") + e.what();
    return res;
  }
  std::ofstream trace, features, occlusion;
  const bool arm = !robot.world_T_links().empty();
  if (!o.out_dir.empty()) {
    std::filesystem::create_directories(o.out_dir);
    trace.open(o.out_dir / "trace.csv");
    if (!trace) throw std::runtime_error((o.out_dir / "trace.csv").string() + ": cannot write");
    trace << "# scenario " << sc.name << ", model " << control::to_string(o.servo.law.model) << ", features "
          << to_string(o.source) << (o.source == FeatureSource::kIdeal ? " (simulator truth, not decoded)" : "")
          << "\n";
    trace << sim::kTraceHeader << "\n";
    trace << std::setprecision(9);
    if (o.write_features) features.open(o.out_dir / "features.jsonl");
    if (o.write_features && arm) {
      occlusion.open(o.out_dir / "occlusion.csv");
      occlusion << "t,visible,hidden_by_arm,on_arm\n";
    }
  }

  for (int k = 0; k < o.max_iterations; ++k) {
    const Eigen::Isometry3d wTc = robot.world_T_camera();
    const sim::LinkPoses links = robot.world_T_links();
    const auto spots = observe(cell, pipeline, o.source, wTc, links, sim::frame_seed(seed, frame++), scratch, nullptr);
    if (occlusion.is_open()) {
      // the truth of the arm's occlusion: spots it hides from the camera, spots it catches
      int visible = 0, hidden = 0, on_arm = 0;
      for (const auto& t : sim::compute_truth(cell, wTc, &links)) {
        visible += t.visible;
        hidden += t.hidden_by_arm;
        on_arm += t.on_arm;
      }
      occlusion << k * sc.dt_s << ',' << visible << ',' << hidden << ',' << on_arm << '\n';
    }
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
    res.iterations = k + 1;
    const bool last = step.control.status != control::ControlStatus::kServoing;
    if (!last) rec.robot_limits = robot.move(step.control.twist, sc.dt_s, sc.workspace).limits;
    res.trace.push_back(rec);
    if (trace.is_open()) {
      trace << rec.t_s;
      for (int i = 0; i < 6; ++i) trace << ',' << rec.twist[i];
      trace << ',' << rec.error_norm << ',' << rec.decoded << ',' << rec.matched << ',' << rec.translation_error_m << ','
            << rec.rotation_error_deg << ',' << sim::limit_names(rec.robot_limits) << '\n';
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
  }
  if (res.stop_reason.empty()) res.stop_reason = "iteration cap (" + std::to_string(o.max_iterations) + ") reached";
  res.final_translation_error_m = sim::translation_error(robot.world_T_camera(), sc.world_T_desired);
  res.final_rotation_error_deg = sim::rotation_error(robot.world_T_camera(), sc.world_T_desired) * kRadToDeg;
  return res;
}

bool run_plot_script(const std::string& script_name, const std::filesystem::path& dir, const std::string& title) {
  const std::filesystem::path script = std::filesystem::path(CELL_SOURCE_DIR) / "bin" / script_name;
  const std::string cmd = "/usr/bin/python3 '" + script.string() + "' '" + dir.string() + "' --title '" + title + "'";
  if (std::system(cmd.c_str()) != 0) {
    std::fprintf(stderr, "cellsim: plotting failed (%s); the tables are in %s\n", cmd.c_str(), dir.c_str());
    return false;
  }
  return true;
}

bool plot_experiment(const std::filesystem::path& dir, const std::string& title) {
  return run_plot_script("plot_trace.py", dir, title);
}

}  // namespace cellsim
