#include "common/progress.hpp"
#include "common/strict_yaml.hpp"
#include "sim/cell/build_cell.hpp"
#include "sim/experiment/experiment.hpp"

#include <optional>

#include "common/output_image.hpp"
#include "common/plot_script.hpp"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <tuple>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "protocol/sim_command.hpp"
#include "servo/vision/overlay.hpp"
#include "sim/session/cell_state_machine.hpp"
#include "sim/session/trace.hpp"
#include "sim/robot/robot.hpp"

namespace experiment {

namespace {

// How the cell's session end reads in the exit-code table
RunEnding ending_of(const sim::SessionEndReport& end, bool diverged) {
  switch (end.kind) {
    case sim::SessionEnd::kConverged: return RunEnding::kConverged;
    case sim::SessionEnd::kStepCap:
    case sim::SessionEnd::kFrameCap: return RunEnding::kCapped;
    case sim::SessionEnd::kServoStopped: return diverged ? RunEnding::kDiverged : RunEnding::kStopped;
    case sim::SessionEnd::kRobotStopped:
    case sim::SessionEnd::kNone: break;
  }
  return RunEnding::kStopped;
}

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

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
  common::write_output_file(file, j.dump(1) + "\n", "scene");
}

}  // namespace

loop::FeatureSource parse_feature_source(const std::string& name) {
  if (name == "decoded") return loop::FeatureSource::kDecoded;
  if (name == "ideal") return loop::FeatureSource::kIdeal;
  if (name == "decoded-ids") return loop::FeatureSource::kDecodedIds;
  if (name == "resolved") return loop::FeatureSource::kResolved;
  throw std::invalid_argument("feature source '" + common::printable(name, 40) +
                              "': expected decoded, ideal, resolved or decoded-ids");
}

namespace {
// what the trace's header says of a source whose points are not the decoder's alone
const char* source_note(loop::FeatureSource s) {
  switch (s) {
    case loop::FeatureSource::kIdeal: return " (simulator truth, not decoded)";
    case loop::FeatureSource::kDecodedIds: return " (the decoder's ids at their true image positions)";
    case loop::FeatureSource::kResolved: return " (simulator truth of the spots the defocus leaves apart, not decoded)";
    case loop::FeatureSource::kDecoded: break;
  }
  return "";
}
}  // namespace

std::string to_string(loop::FeatureSource s) {
  switch (s) {
    case loop::FeatureSource::kIdeal: return "ideal";
    case loop::FeatureSource::kDecodedIds: return "decoded-ids";
    case loop::FeatureSource::kResolved: return "resolved";
    case loop::FeatureSource::kDecoded: break;
  }
  return "decoded";
}

calibration::CameraIntrinsics camera_intrinsics_of(const sim::CameraSpec& cam) {
  return {cam.intrinsics.fx, cam.intrinsics.fy, cam.intrinsics.cx, cam.intrinsics.cy, cam.distortion};
}
calibration::CameraIntrinsics camera_intrinsics_of(const sim::Cell& cell) { return camera_intrinsics_of(cell.scenario.camera); }

calibration::ProjectorModel projector_model_of(const sim::Cell& cell) {
  const sim::ProjectorSpec& p = cell.projector->spec();
  calibration::ProjectorModel pm;
  pm.fx = p.intrinsics.fx;
  pm.fy = p.intrinsics.fy;
  pm.cx = p.intrinsics.cx;
  pm.cy = p.intrinsics.cy;
  pm.spot_pitch_px = p.spot_pitch_px;
  pm.rows = cell.projector->pattern().rows;
  pm.cols = cell.projector->pattern().cols;
  pm.world_T_projector = p.world_T_projector;
  pm.on_camera = cell.scenario.projector.on_camera;
  return pm;
}

servo::ServoConfig servo_config_for(const sim::Cell& cell) {
  servo::ServoConfig c;
  c.camera = camera_intrinsics_of(cell);
  // the camera's colour crosstalk, calibrated as its intrinsics are
  c.decoder.segmentation.crosstalk = cell.scenario.camera.crosstalk;
  c.projector = projector_model_of(cell);
  // the projector's calibration is there for triangulation; decoding with it is an option
  // (`cellsim experiment --epipolar`), so runs compare with a servo started without --projector
  c.decoder.epipolar.enabled = false;
  c.law.max_linear_mps = cell.scenario.robot.max_linear_mps;
  c.law.max_angular_radps = cell.scenario.robot.max_angular_radps;
  return c;
}



calibration::ProjectorModel believed_projector(const calibration::ProjectorModel& truth, const sim::DrawnErrors& d) {
  calibration::ProjectorModel p = truth;
  p.world_T_projector = truth.world_T_projector * d.projector_delta;
  if (truth.on_camera) p.on_camera = *truth.on_camera * d.projector_delta;  // its mount as calibrated
  return p;
}

namespace {

// features.jsonl: the points the law used at one iteration, with their depths and weights
nlohmann::json features_line(int k, const ExperimentOptions& o, const loop::LoopExchange& x,
                             const std::vector<char>& off_centre) {
  const servo::StepResult& step = *x.reply.step;
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
    if (o.outlier_fraction > 0)
      p["swapped"] = std::find(x.wrong.begin(), x.wrong.end(), std::make_pair(m.row, m.col)) != x.wrong.end();
    if (i < off_centre.size()) p["off_centre"] = off_centre[i] != 0;
    // the robust law's weight of the point (only with one: the plain law's are all 1)
    if (o.servo.law.robust != control::RobustEstimator::kNone) {
      const double w = i < step.control.weights.size() ? step.control.weights[i] : std::nan("");
      p["weight"] = std::isfinite(w) ? nlohmann::json(w) : nlohmann::json(nullptr);
    }
    j["points"].push_back(p);
  }
  // the features held out by their taught points (ServoConfig::taught_points): not among the points
  if (o.servo.taught_points) j["held_by_taught"] = step.held_by_taught;
  j["v"] = std::vector<double>(step.control.twist.data(), step.control.twist.data() + 6);
  if (o.outlier_fraction > 0) j["swapped"] = x.swapped;
  return j;
}

// Which of the points the law took lie off the true centre of the spot their id names (more
// than kMatchTolerancePx, in the servo's own normalised coordinates scaled by its focal
// lengths), or name a spot the camera does not see: the truth of this frame.
std::vector<char> off_centre_of(const sim::Cell& cell, const loop::LoopExchange& x,
                                const calibration::CameraIntrinsics& camera) {
  constexpr double kMatchTolerancePx = 2.0;  // decode-sweep's: a right id within it
  const servo::StepResult& step = *x.reply.step;
  std::vector<char> off(step.matched.size(), 0);
  if (step.matched.empty()) return off;
  const std::vector<sim::SpotTruth> truth =
      sim::compute_truth(cell, x.frame.scene_world_T_camera, &x.frame.scene_world_T_links);
  const int cols = cell.projector->pattern().cols;
  for (std::size_t i = 0; i < step.matched.size(); ++i) {
    const control::MatchedPoint& m = step.matched[i];
    const sim::SpotTruth& t = truth[static_cast<std::size_t>(m.row) * cols + m.col];
    if (!t.visible) {
      off[i] = 1;
      continue;
    }
    const Eigen::Vector2d xy = calibration::normalise(camera, t.uv);
    off[i] = std::hypot(camera.fx * (xy.x() - m.x), camera.fy * (xy.y() - m.y)) > kMatchTolerancePx;
  }
  return off;
}

}  // namespace

namespace {

// The loop an experiment runs: the scenario with the options' errors and delays; the servo and
// the robot's controller told the draw (this run's, from `seed`), the simulator keeping the truth.
loop::LoopSetup loop_setup(const sim::Cell& cell, const ExperimentOptions& o, std::uint64_t seed) {
  loop::LoopSetup setup;
  setup.latency = o.latency.value_or(cell.scenario.latency);
  const sim::CalibrationErrors errors = o.errors.value_or(cell.scenario.errors);
  const sim::Scenario& sc = cell.scenario;
  setup.servo = o.servo;
  sim::RobotBelief belief;
  if (errors.any()) {
    const sim::DrawnErrors drawn = sim::scenario_errors(sc, errors, seed);
    setup.servo.camera = camera_intrinsics_of(sim::believed_camera(sc.camera, drawn));
    if (setup.servo.projector) setup.servo.projector = believed_projector(*setup.servo.projector, drawn);
    belief = drawn.robot;
  }
  setup.robot = sim::make_robot(cell, &belief);
  setup.noise_seed = seed;
  setup.source = o.source;
  setup.outlier_fraction = o.outlier_fraction;
  setup.loss_fraction = o.loss_fraction;
  // the servo, told so, rejects a frame that comes without its white frame (as `servo run --white-frame`)
  setup.white_frame = setup.servo.white_frame = o.white_frame || o.servo.white_frame;
  setup.white_frame_lead = o.white_frame_lead;
  setup.max_steps = o.max_iterations;
  setup.render_threads = o.render_threads;
  return setup;
}

IterationRecord record_of(const sim::TraceRow& r) {
  IterationRecord rec;
  rec.t_s = r.time_s;
  rec.twist = r.twist;
  rec.error_norm = r.status ? r.status->error_norm : std::nan("");
  rec.decoded = r.status ? static_cast<int>(r.status->decoded) : 0;
  rec.matched = r.status ? static_cast<int>(r.status->matched) : 0;
  rec.translation_error_m = r.translation_error_m;
  rec.rotation_error_deg = r.rotation_error_deg;
  rec.robot_limits = r.robot_limits;
  return rec;
}

// One experiment on the in-memory loop, as `cellsim serve --autorun` runs it over DDS: TEACH,
// then RESET and START once the servo is taught, then rounds until the cell ends the session.
class Experiment {
 public:
  Experiment(const sim::Cell& cell, const ExperimentOptions& o)
      : cell_(cell), o_(o), seed_(o.noise_seed ? o.noise_seed : cell.scenario.seed),
        initial_(o.initial.value_or(cell.scenario.world_T_initial())), loop_(cell, loop_setup(cell, o, seed_)) {}

  ExperimentResult run() {
    if (o_.progress)
      progress_ = std::make_unique<common::Progress>("experiment " + scenario().name,
                                                     static_cast<std::size_t>(o_.max_iterations), "iterations");
    open_trace();
    loop_.set_tap(o_.tap);
    loop_.command({static_cast<int>(cell_dds::SimCommand::kTeach), "", 0, std::nullopt});
    int idle_rounds = 0;
    for (;;) {
      std::vector<loop::LoopExchange> exchanges;
      const sim::CellOutput out = loop_.round(exchanges);
      for (const auto& r : out.trace) record(r);
      for (const auto& x : exchanges) {
        if (x.frame.teach) {
          if (!taught(x)) return res_;
        } else if (x.frame.applies_twist) {
          stepped(x);
        }
      }
      for (const auto& line : out.refusals) refused_reset(line);
      if (!res_.stop_reason.empty()) return res_;
      if (o_.cancelled && o_.cancelled()) {
        res_.stop_reason = "cancelled";
        ended_ = RunEnding::kStopped;
        break;
      }
      if (out.done) break;
      // the cell ordered nothing: after the teach frame it waits for commands; more is a stall
      idle_rounds = exchanges.empty() ? idle_rounds + 1 : 0;
      if (idle_rounds > 3) {
        res_.stop_reason = started_ ? "the cell made no frame" : "no teach frame";
        ended_ = started_ ? RunEnding::kStopped : RunEnding::kNotTaught;
        break;
      }
    }
    finish();
    if (progress_) progress_->finish(static_cast<std::size_t>(k_));
    return res_;
  }

 private:
  const sim::Scenario& scenario() const { return loop_.cell().scenario(); }

  void open_trace() {
    if (o_.out_dir.empty()) return;
    common::make_output_folder(o_.out_dir);
    trace_.open(o_.out_dir / "trace.csv", "trace");
    trace_ << "# scenario " << scenario().name << ", model " << control::to_string(o_.servo.law.model) << ", features "
           << to_string(o_.source) << source_note(o_.source)
           << ", visual features " << control::to_string(o_.servo.law.features) << "\n"
           << sim::kTraceHeader << "\n"
           << std::setprecision(9);
  }

  // a trace row of the cell, with the law's own numbers of its step (they come a round earlier)
  void record(const sim::TraceRow& r) {
    IterationRecord rec = record_of(r);
    if (!step_extras_.empty()) {
      rec.feature_rms = step_extras_.front().feature_rms;
      rec.swapped = step_extras_.front().swapped;
      rec.off_centre = step_extras_.front().off_centre;
      rec.condition = step_extras_.front().condition;
      step_extras_.pop_front();
    }
    res_.trace.push_back(rec);
    if (trace_.is_open()) sim::write_trace_row(trace_, r, false);
  }

  // The teach frame's answer: the servo taught, the robot sent to the initial pose and started.
  // False when the run cannot go on.
  bool taught(const loop::LoopExchange& x) {
    if (!x.reply.taught) {
      // the servo's advice to a DDS client ("send TEACH again") is not for an in-process run,
      // which ends here
      std::string why = x.reply.reason;
      if (const std::size_t advice = why.find(": send TEACH again"); advice != std::string::npos) why.erase(advice);
      res_.stop_reason = "not taught: " + why;
      res_.ending = RunEnding::kNotTaught;
      return false;
    }
    res_.decoded_desired = static_cast<int>(x.reply.matched);
    // the teach frame's answer is applied by the next round; the RESET waits behind it
    if (!loop_.command({static_cast<int>(cell_dds::SimCommand::kReset), "", 0, initial_})) {
      res_.stop_reason = "initial pose refused (" + scenario().file.filename().string() + ")";
      res_.ending = RunEnding::kRefused;
      return false;
    }
    loop_.command({static_cast<int>(cell_dds::SimCommand::kStart), "", 0, std::nullopt});
    started_ = true;
    if (o_.out_dir.empty()) return true;
    write_overlay(x, "desired.png");
    write_scene(cell_, scenario().world_T_desired, initial_, o_.out_dir / "scene.json");
    if (o_.write_features) {
      features_.open(o_.out_dir / "features.jsonl", "features log");
      if (!x.frame.world_T_links.empty()) {
        occlusion_.open(o_.out_dir / "occlusion.csv", "occlusion table");
        occlusion_ << "t,visible,hidden_by_arm,on_arm\n";
      }
    }
    return true;
  }

  // The frame's image with the ids the servo decoded in it (the paper's Fig. 4a-b; plot_trace.py
  // puts them beside the velocities and |e| in fig4.png). Only where an image was decoded
  // (decoded features, decoded ids): the truth's sources read none.
  void write_overlay(const loop::LoopExchange& x, const char* name) const {
    if (o_.out_dir.empty() || x.image.empty() || !x.reply.spots) return;
    vision::DecodeResult r;
    for (const servo::ImageSpot& s : *x.reply.spots) r.decoded.push_back({s.row, s.col, s.u, s.v, 0});
    cv::Mat bgr;
    cv::cvtColor(vision::draw_overlay(x.image, r), bgr, cv::COLOR_RGB2BGR);
    common::write_output_image(o_.out_dir / name, bgr);
  }

  // An applied frame: what the law did, for the trace, features.jsonl and occlusion.csv.
  void stepped(const loop::LoopExchange& x) {
    if (k_ == 0) res_.decoded_initial = static_cast<int>(x.reply.decoded);
    if (k_ == 0) write_overlay(x, "initial.png");
    // the truth of what the law took (decoded features only: ideal ones are the truth)
    const std::vector<char> off_centre = o_.source == loop::FeatureSource::kDecoded && x.reply.step
                                             ? off_centre_of(cell_, x, loop_.servo().pipeline().config().camera)
                                             : std::vector<char>{};
    step_extras_.push_back({x.reply.step ? x.reply.step->control.feature_rms : 0.0, x.swapped,
                            x.reply.step ? x.reply.step->control.condition : 0.0,
                            static_cast<int>(std::count(off_centre.begin(), off_centre.end(), 1))});
    const Eigen::Vector3d at = x.frame.world_T_camera.translation();
    if (k_ == 0) res_.straight_line_m = (at - scenario().world_T_desired.translation()).norm();
    if (last_position_) res_.path_length_m += (at - *last_position_).norm();
    last_position_ = at;
    if (occlusion_.is_open()) {
      // the truth of the arm's occlusion: spots it hides from the camera, spots it catches
      int visible = 0, hidden = 0, on_arm = 0;
      for (const auto& t : sim::compute_truth(cell_, x.frame.world_T_camera, &x.frame.world_T_links)) {
        visible += t.visible;
        hidden += t.hidden_by_arm;
        on_arm += t.on_arm;
      }
      occlusion_ << k_ * scenario().dt_s << ',' << visible << ',' << hidden << ',' << on_arm << '\n';
    }
    if (features_.is_open() && x.reply.step) features_ << features_line(k_, o_, x, off_centre).dump() << '\n';
    ++k_;
    if (progress_) progress_->at(static_cast<std::size_t>(k_));
  }

  // the RESET to the initial pose waited behind the teach frame: its refusal comes later
  void refused_reset(const std::string& line) {
    const std::string key = "RESET refused: ";
    const std::size_t at = line.find(key);
    if (at == std::string::npos || !res_.stop_reason.empty()) return;
    res_.stop_reason =
        "initial pose refused (" + scenario().file.filename().string() + "): " + line.substr(at + key.size());
    res_.ending = RunEnding::kRefused;
  }

  void finish() {
    res_.iterations = static_cast<int>(res_.trace.size());
    const sim::SessionEndReport& end = loop_.cell().session_end();
    if (res_.stop_reason.empty()) res_.stop_reason = end.reason;
    res_.converged = end.kind == sim::SessionEnd::kConverged;
    res_.robot_stopped = end.kind == sim::SessionEnd::kRobotStopped;
    res_.diverged = end.kind == sim::SessionEnd::kServoStopped && end.reason.rfind("diverging", 0) == 0;
    res_.ending = ended_ ? *ended_ : ending_of(end, res_.diverged);
    for (std::size_t i = 1; i < res_.trace.size(); ++i)
      res_.error_rise += std::max(0.0, res_.trace[i].error_norm - res_.trace[i - 1].error_norm);
    if (!res_.trace.empty() && res_.trace.front().error_norm > 0) {
      res_.error_rise /= res_.trace.front().error_norm;
      double top = 0;
      for (const auto& r : res_.trace) top = std::max(top, r.error_norm);
      res_.max_error_ratio = top / res_.trace.front().error_norm;
    }
    for (const auto& r : res_.trace) {
      res_.off_centre_max = std::max(res_.off_centre_max, r.off_centre);
      res_.off_centre_total += r.off_centre;
    }
    std::vector<double> conditions;
    for (const auto& r : res_.trace)
      if (r.condition > 0 && std::isfinite(r.condition)) conditions.push_back(r.condition);
    if (!conditions.empty()) {
      std::sort(conditions.begin(), conditions.end());
      res_.condition_median = conditions[conditions.size() / 2];
      res_.condition_max = conditions.back();
    }
    // the trace says why the run ended, as the service's trace does
    if (trace_.is_open()) trace_ << "# session ended: " << res_.stop_reason << '\n';
    for (common::OutputStream* s : {&trace_, &features_, &occlusion_}) s->close();  // a failed write is said
    const Eigen::Isometry3d wTc = loop_.cell().world_T_camera();
    const sim::GoalError goal = sim::goal_error(wTc, scenario().world_T_desired, cell_.goal_plane);
    res_.final_translation_error_m = goal.translation_m;
    res_.final_rotation_error_deg = goal.rotation_rad * kRadToDeg;
  }

  const sim::Cell& cell_;
  const ExperimentOptions& o_;
  std::uint64_t seed_;
  Eigen::Isometry3d initial_;
  loop::InMemoryLoop loop_;
  ExperimentResult res_;
  common::OutputStream trace_, features_, occlusion_;
  struct StepExtras {
    double feature_rms;
    int swapped;
    double condition;
    int off_centre;
  };
  std::deque<StepExtras> step_extras_;  // per applied step, in order
  std::optional<Eigen::Vector3d> last_position_;  // the camera's, at the last applied frame
  int k_ = 0;                                       // applied frames so far
  std::unique_ptr<common::Progress> progress_;      // with ExperimentOptions::progress
  bool started_ = false;
  std::optional<RunEnding> ended_;  // set where the run stops before the cell ends the session
};

}  // namespace

ExperimentResult run_experiment(const sim::Cell& cell, const ExperimentOptions& o) {
  loop::check_injections(o.source, o.outlier_fraction, o.loss_fraction);  // before an output is made
  return Experiment(cell, o).run();
}

control::VisualFeatures visual_features_or_default(const std::string& name, const servo::ServoConfig& config) {
  if (!name.empty()) return control::parse_visual_features(name);
  return config.projector && config.projector->on_camera ? control::VisualFeatures::kPlane : control::VisualFeatures::kPoints;
}

double desired_depth(const sim::Cell& cell) {
  double sum = 0;
  int n = 0;
  for (const auto& t : sim::compute_truth(cell, cell.scenario.world_T_desired))
    if (t.visible) sum += t.depth_m, ++n;
  return n ? sum / n : 1.0;
}

loop::LoopSetup experiment_loop_setup(const sim::Cell& cell, const ExperimentOptions& o, std::uint64_t seed) {
  return loop_setup(cell, o, seed);
}

bool run_plot_script(const std::string& script_name, const std::filesystem::path& dir, const std::string& title) {
  return common::run_plot_script("cellsim", script_name, dir, title);
}

bool plot_experiment(const std::filesystem::path& dir, const std::string& title) {
  return run_plot_script("plot_trace.py", dir, title);
}

}  // namespace experiment
