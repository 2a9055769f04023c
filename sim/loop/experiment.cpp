#include "sim/loop/experiment.hpp"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>

#include "sim/cell/trace.hpp"
#include "sim/robot/robot.hpp"
#include "sim/robot/twist_delay.hpp"

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

nlohmann::json matrix_json(const Eigen::Isometry3d& T) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
  return rows;
}

// What the Fig. 5a-b drawings need: where the camera is taught and starts, where the
// projector is, and where the spots seen at the desired pose land (the truth).
void write_scene(const sim::Cell& cell, const Eigen::Isometry3d& desired, const Eigen::Isometry3d& initial,
                 const std::filesystem::path& file) {
  nlohmann::json j;
  j["camera_desired"] = matrix_json(desired);
  j["camera_initial"] = matrix_json(initial);
  j["projector"] = matrix_json(cell.scenario.projector.world_T_projector);
  j["spots"] = nlohmann::json::array();
  for (const auto& t : sim::compute_truth(cell, desired))
    if (t.visible) j["spots"].push_back({{"row", t.row}, {"col", t.col}, {"point_w", {t.point_w.x(), t.point_w.y(), t.point_w.z()}}});
  j["objects"] = nlohmann::json::array();
  for (std::size_t i = 0; i < cell.scenario.objects.size(); ++i) {
    const auto& o = cell.scenario.objects[i];
    j["objects"].push_back({{"name", o.name}, {"pose", matrix_json(o.world_T_object)}});
  }
  std::ofstream out(file);
  if (!out) throw std::runtime_error(file.string() + ": cannot write");
  out << j.dump(1) << "\n";
}

}  // namespace

FeatureSource parse_feature_source(const std::string& name) {
  if (name == "decoded") return FeatureSource::kDecoded;
  if (name == "ideal") return FeatureSource::kIdeal;
  throw std::invalid_argument("feature source '" + name + "': expected decoded or ideal");
}

std::string to_string(FeatureSource s) { return s == FeatureSource::kIdeal ? "ideal" : "decoded"; }

control::CameraIntrinsics camera_intrinsics_of(const sim::CameraSpec& cam) {
  return {cam.intrinsics.fx, cam.intrinsics.fy, cam.intrinsics.cx, cam.intrinsics.cy, cam.distortion};
}
control::CameraIntrinsics camera_intrinsics_of(const sim::Cell& cell) { return camera_intrinsics_of(cell.scenario.camera); }

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



control::ProjectorModel believed_projector(const control::ProjectorModel& truth, const sim::DrawnErrors& d) {
  control::ProjectorModel p = truth;
  p.world_T_projector = truth.world_T_projector * d.projector_delta;
  return p;
}

std::string robot_stop_reason(const std::string& event) {
  // the service's wording tells a client what to do ("... until RESET"); a run just ends
  const std::string suffix = ": robot stopped until RESET";
  if (event.size() >= suffix.size() && event.compare(event.size() - suffix.size(), suffix.size(), suffix) == 0)
    return event.substr(0, event.size() - suffix.size());
  return event;
}

int inject_outliers(std::vector<servo::ImageSpot>& spots, double fraction, std::uint64_t seed,
                    std::vector<std::pair<int, int>>* wrong) {
  if (!(fraction > 0) || spots.size() < 2) return 0;
  const std::size_t n = std::min(spots.size(), std::max<std::size_t>(2, static_cast<std::size_t>(std::lround(fraction * static_cast<double>(spots.size())))));
  std::mt19937_64 rng(seed);
  std::vector<std::size_t> pick(spots.size());
  for (std::size_t i = 0; i < pick.size(); ++i) pick[i] = i;
  for (std::size_t i = 0; i < n; ++i) std::swap(pick[i], pick[i + rng() % (pick.size() - i)]);
  // a cycle over the chosen spots: each takes the next one's id, so none keeps its own
  const int row0 = spots[pick[0]].row, col0 = spots[pick[0]].col;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    spots[pick[i]].row = spots[pick[i + 1]].row;
    spots[pick[i]].col = spots[pick[i + 1]].col;
  }
  spots[pick[n - 1]].row = row0;
  spots[pick[n - 1]].col = col0;
  if (wrong)
    for (std::size_t i = 0; i < n; ++i) wrong->emplace_back(spots[pick[i]].row, spots[pick[i]].col);
  return static_cast<int>(n);
}

ExperimentResult run_experiment(const sim::Cell& cell, const ExperimentOptions& o) {
  const sim::Scenario& sc = cell.scenario;
  const std::uint64_t seed = o.noise_seed ? o.noise_seed : sc.seed;
  const sim::CalibrationErrors errors = o.errors.value_or(sc.errors);
  const sim::Latency latency = o.latency.value_or(sc.latency);
  const std::unique_ptr<sim::Robot> robot_owner = sim::make_robot(cell);
  sim::Robot& robot = *robot_owner;
  servo::ServoConfig config = o.servo;
  // the simulator keeps the truth; the servo and the robot's controller get the draw (and
  // the robot forgets what make_robot drew from the scenario when the options say otherwise)
  robot.set_belief({});
  if (errors.any()) {
    const sim::DrawnErrors drawn = sim::scenario_errors(sc, errors, seed);
    config.camera = camera_intrinsics_of(sim::believed_camera(sc.camera, drawn));
    if (config.projector) config.projector = believed_projector(*config.projector, drawn);
    robot.set_belief(drawn.robot);
  }
  servo::ServoPipeline pipeline(pattern::WindowTable(cell.projector->pattern(), {3, 3}), config);
  sim::RenderScratch scratch;
  ExperimentResult res;

  // teach by showing: the robot at the desired pose, s* from what the camera sees there
  std::uint64_t frame = 0;
  const auto taught = observe(cell, pipeline, o.source, robot.world_T_camera(), robot.world_T_links(),
                              sim::frame_seed(seed, frame++), scratch, nullptr);
  res.decoded_desired = pipeline.teach(taught, robot.reported_world_T_camera());

  try {
    robot.reset(o.initial.value_or(sc.world_T_initial()));
  } catch (const std::invalid_argument& e) {
    res.stop_reason = "initial pose refused (" + sc.file.filename().string() + "): " + e.what();
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
    write_scene(cell, sc.world_T_desired, robot.world_T_camera(), o.out_dir / "scene.json");
    if (o.write_features) features.open(o.out_dir / "features.jsonl");
    if (o.write_features && arm) {
      occlusion.open(o.out_dir / "occlusion.csv");
      occlusion << "t,visible,hidden_by_arm,on_arm\n";
    }
  }

  // the loop's delays: the scenes the camera has not delivered yet, and the twists on their
  // way to the robot
  sim::FrameDelay<std::pair<Eigen::Isometry3d, sim::LinkPoses>> scenes(latency.acquisition_frames);
  sim::TwistDelay delay(latency.processing_frames, latency.actuation_s);
  control::DivergenceWatch divergence(config.divergence_ratio);
  control::SafeStopWatch safe_stop(config.safe_stop_frames);

  for (int k = 0; k < o.max_iterations; ++k) {
    const Eigen::Isometry3d wTc = robot.world_T_camera();
    const sim::LinkPoses links = robot.world_T_links();
    // the image of this frame shows the scene of acquisition_frames ago (or the start)
    const auto& [scene_wTc, scene_links] = scenes.push({wTc, links});
    const auto spots =
        observe(cell, pipeline, o.source, scene_wTc, scene_links, sim::frame_seed(seed, frame++), scratch, nullptr);
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
    // the outlier injection works on a copy, made only when it is on
    std::vector<servo::ImageSpot> swapped_spots;
    std::vector<std::pair<int, int>> wrong_ids;
    int swapped = 0;
    if (o.outlier_fraction > 0) {
      swapped_spots = spots;
      swapped = inject_outliers(swapped_spots, o.outlier_fraction,
                                sim::frame_seed(seed ^ 0x6f75746c69657273ull, frame), &wrong_ids);
    }
    const servo::StepResult step =
        pipeline.step(o.outlier_fraction > 0 ? swapped_spots : spots, robot.reported_world_T_camera());

    IterationRecord rec;
    rec.t_s = k * sc.dt_s;
    rec.twist = step.control.twist;
    rec.error_norm = step.control.error_norm;
    rec.feature_rms = step.control.feature_rms;
    rec.decoded = step.decoded;
    rec.matched = static_cast<int>(step.matched.size());
    rec.translation_error_m = sim::translation_error(wTc, sc.world_T_desired);
    rec.rotation_error_deg = sim::rotation_error(wTc, sc.world_T_desired) * kRadToDeg;
    rec.swapped = swapped;
    res.iterations = k + 1;
    // as the servo service decides (servo_state_machine.cpp): converged, a runaway, and a safe
    // stop that has lasted end the run; a passing safe stop holds the robot (its twist is zero)
    const bool lasting_safe_stop = safe_stop.lasting(step.control.status);
    bool last = step.control.status == control::ControlStatus::kConverged || lasting_safe_stop;
    if (step.control.status == control::ControlStatus::kServoing) {
      res.stop_reason = divergence.check(step.control.error_norm);
      res.diverged = last = !res.stop_reason.empty();
    }
    // the robot stopped by itself (a collision, a fault): the run ends, as the service's arm
    // holds still until RESET; a step refused at the workspace border is not a stop
    std::string robot_event;
    if (!last) {
      const sim::MotionReport motion = delay.step(robot, step.control.twist, rec.t_s, sc.dt_s, sc.workspace);
      rec.robot_limits = motion.limits;
      if (sim::stopped_until_reset(motion)) robot_event = motion.event;
    }
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
        // the robust law's weight of the point (only with one: the plain law's are all 1)
        if (o.outlier_fraction > 0)
          p["swapped"] = std::find(wrong_ids.begin(), wrong_ids.end(), std::make_pair(m.row, m.col)) != wrong_ids.end();
        if (o.servo.law.robust != control::RobustEstimator::kNone) {
          const double w = i < step.control.weights.size() ? step.control.weights[i] : std::nan("");
          p["weight"] = std::isfinite(w) ? nlohmann::json(w) : nlohmann::json(nullptr);
        }
        j["points"].push_back(p);
      }
      j["v"] = std::vector<double>(step.control.twist.data(), step.control.twist.data() + 6);
      if (o.outlier_fraction > 0) j["swapped"] = swapped;
      features << j.dump() << '\n';
    }
    if (step.control.status == control::ControlStatus::kConverged) {
      res.converged = true;
      res.stop_reason = "converged: " + step.control.reason;
      break;
    }
    if (lasting_safe_stop) {
      res.stop_reason = "safe stop: " + step.control.reason + " (" + std::to_string(safe_stop.frames()) + " frames)";
      break;
    }
    if (!robot_event.empty()) {
      // the arm holds still until a reset: iterating on would only repeat the last frame
      res.robot_stopped = true;
      res.stop_reason = "robot stop: " + robot_stop_reason(robot_event);
      break;
    }
    if (res.diverged) break;
  }
  if (res.stop_reason.empty()) res.stop_reason = "iteration cap (" + std::to_string(o.max_iterations) + ") reached";
  for (std::size_t i = 1; i < res.trace.size(); ++i)
    res.error_rise += std::max(0.0, res.trace[i].error_norm - res.trace[i - 1].error_norm);
  if (!res.trace.empty() && res.trace.front().error_norm > 0) {
    res.error_rise /= res.trace.front().error_norm;
    double top = 0;
    for (const auto& r : res.trace) top = std::max(top, r.error_norm);
    res.max_error_ratio = top / res.trace.front().error_norm;
  }
  res.final_translation_error_m = sim::translation_error(robot.world_T_camera(), sc.world_T_desired);
  res.final_rotation_error_deg = sim::rotation_error(robot.world_T_camera(), sc.world_T_desired) * kRadToDeg;
  return res;
}

bool run_plot_script(const std::string& script_name, const std::filesystem::path& dir, const std::string& title) {
  const std::filesystem::path script = std::filesystem::path(CELL_SOURCE_DIR) / "bin" / script_name;
  // an argument vector, never a shell: the title comes from a scenario's name: and the folder
  // from the command line, and either may hold quotes (issue 18, item 19)
  std::vector<std::string> args = {"/usr/bin/python3", script.string(), dir.string(), "--title", title};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  int status = 0;
  const int err = posix_spawn(&pid, argv[0], nullptr, nullptr, argv.data(), environ);
  const bool ok = err == 0 && waitpid(pid, &status, 0) == pid && WIFEXITED(status) && WEXITSTATUS(status) == 0;
  if (!ok) {
    std::fprintf(stderr, "cellsim: plotting failed (%s %s); the tables are in %s\n", args[0].c_str(), script.c_str(),
                 dir.c_str());
    return false;
  }
  return true;
}

bool plot_experiment(const std::filesystem::path& dir, const std::string& title) {
  return run_plot_script("plot_trace.py", dir, title);
}

}  // namespace cellsim
