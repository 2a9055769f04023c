// `cellsim`: the robot-cell simulator's command line. `render` renders one frame offline.
#include <CLI/CLI.hpp>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <functional>
#include <tuple>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/cli_help.hpp"
#include "common/output_image.hpp"
#include "sim/app/experiment_recording.hpp"
#include "sim/app/live_bridge.hpp"
#include "dds/cli_flags.hpp"
#include "common/cli_numbers.hpp"
#include "servo/calibration/projector_calibration.hpp"
#include "servo/pattern/pattern_file.hpp"
#include "servo/pattern/window_table.hpp"
#include "sim/cell/build_cell.hpp"
#include "sim/experiment/decode_sweep.hpp"
#include "servo/vision/decoder_options.hpp"
#include "sim/experiment/experiment.hpp"
#include "common/strict_yaml.hpp"
#include "dds/topics.hpp"
#include "sim/experiment/campaign.hpp"
#include "sim/experiment/divergence_search.hpp"
#include "sim/experiment/study.hpp"
#include "sim/service/sim_service.hpp"
#include "dds/participant.hpp"
#include "sim/geometry/se3.hpp"
#include "sim/render/renderer.hpp"

namespace {

// A run's ending in the exit-code table (common/exit_codes.hpp, README.md)
int exit_code_of(experiment::RunEnding e) {
  namespace x = common::exit_code;
  switch (e) {
    case experiment::RunEnding::kConverged: return x::kDone;
    case experiment::RunEnding::kDiverged: return x::kDiverged;
    case experiment::RunEnding::kCapped: return x::kCapped;
    case experiment::RunEnding::kNotTaught: return x::kNotTaught;
    case experiment::RunEnding::kRefused: return x::kRefused;
    case experiment::RunEnding::kStopped: break;
  }
  return x::kStopped;
}

nlohmann::json pose_json(const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.rotation());
  return {{"position_m", {T.translation().x(), T.translation().y(), T.translation().z()}},
          {"orientation_xyzw", {q.x(), q.y(), q.z(), q.w()}}};
}

void write_png_rgb(const std::string& path, const cv::Mat& rgb) {
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  common::write_output_image(path, bgr);
}

// The scenario a command runs: its file, and the override of its spec the command line gives,
// applied before the spec is resolved: --pattern FILE, the pattern the projector casts (and the
// in-process servo decodes) instead of the scenario's (issue 19: both patterns stay runnable).
struct ScenarioArg {
  std::string file;
  std::string pattern;
  void add(CLI::App* c, const char* what = "scenario YAML file", bool required = true) {
    CLI::Option* o = c->add_option("scenario", file, what);
    if (required) o->required();
    c->add_option("--pattern", pattern,
                  "pattern file the projector casts instead of the scenario's (e.g. "
                  "servo/pattern/data/marray_20x20_k3_w3_d3.txt, the distance-3 one)");
  }
  sim::ResolvedScenario load() const {
    sim::Scenario s = sim::read_scenario(file);
    if (!pattern.empty()) {
      std::error_code ec;
      s.projector.pattern = std::filesystem::absolute(pattern, ec);
      pattern::load_pattern(s.projector.pattern, {3, 3});  // one line naming the file if it is not a pattern
    }
    return sim::resolve(std::move(s));
  }
};

// An observer's view is a picture of the cell for a person, not a frame for the servo: lit by the
// ambient light alone (a twentieth of the projector's), the arm and the walls came out nearly
// black. It is rendered again with the camera's exposure raised (at most 16 times) so that its
// brightest 1 % reaches 230 of 255: the same scene and noise draw, a readable picture.
cv::Mat exposed_for_observer(const sim::Cell& cell, const Eigen::Isometry3d& view, std::uint64_t seed,
                             const sim::LinkPoses& links, const cv::Mat& first) {
  std::vector<std::uint8_t> values;
  values.reserve(first.total());
  for (int r = 0; r < first.rows; ++r)
    for (int c = 0; c < first.cols; ++c) {
      const cv::Vec3b& p = first.at<cv::Vec3b>(r, c);
      values.push_back(std::max({p[0], p[1], p[2]}));
    }
  auto at = values.begin() + static_cast<std::ptrdiff_t>(0.99 * static_cast<double>(values.size()));
  std::nth_element(values.begin(), at, values.end());
  const double gain = std::clamp(230.0 / std::max<double>(*at, 1.0), 1.0, 16.0);
  if (gain <= 1.0) return first;
  sim::CameraSpec sensor = cell.scenario.camera;
  sensor.exposure *= gain;
  std::printf("observer view: exposure x%.1f (its brightest 1 %% at 230 of 255)\n", gain);
  return sim::render_image(cell, view, seed, nullptr, &sensor, &links);
}

int run_render(const ScenarioArg& scenario_arg, const std::string& pose_spec, const std::string& out_png,
               const std::string& truth_file, std::uint64_t frame, const std::vector<double>& observer,
               const std::string& white_png) {
  const sim::ResolvedScenario scenario = scenario_arg.load();
  const Eigen::Isometry3d wTc = sim::resolve_pose(scenario, pose_spec);
  const auto cell = sim::build_cell(scenario);
  // the robot at the pose: the arm's links are drawn, lit and cast shadows
  const std::unique_ptr<sim::Robot> robot = sim::make_robot(*cell);
  try {
    robot->reset(wTc);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(scenario_arg.file + ": --pose '" + common::printable(pose_spec) + "': " + e.what());
  }
  const sim::LinkPoses links = robot->world_T_links();
  Eigen::Isometry3d view = wTc;
  if (observer.size() == 6) {
    const Eigen::Vector3d eye(observer[0], observer[1], observer[2]), target(observer[3], observer[4], observer[5]);
    if ((target - eye).norm() < 1e-6) throw std::invalid_argument("--observer: the eye and the target coincide");
    view = sim::look_at(eye, target, Eigen::Vector3d::UnitZ());
  }
  cv::Mat image = sim::render_image(*cell, view, sim::frame_seed(scenario.seed, frame), nullptr, nullptr, &links);
  if (observer.size() == 6) image = exposed_for_observer(*cell, view, sim::frame_seed(scenario.seed, frame), links, image);
  write_png_rgb(out_png, image);
  if (!white_png.empty())
    write_png_rgb(white_png, sim::render_image(*cell, view, sim::white_frame_seed(sim::frame_seed(scenario.seed, frame)),
                                               nullptr, nullptr, &links, sim::Cast::kWhite));
  const auto truth = sim::compute_truth(*cell, wTc, &links);
  int visible = 0;
  for (const auto& t : truth) visible += t.visible;
  if (!truth_file.empty()) {
    nlohmann::json j;
    j["scenario"] = scenario.name;
    j["camera_pose"] = pose_json(wTc);
    j["camera_pose"]["frame_id"] = "world";
    const auto q = robot->joint_positions();
    if (q.size() > 0) {
      j["joints"] = nlohmann::json::object();
      const auto names = robot->joint_names();
      for (Eigen::Index i = 0; i < q.size(); ++i) j["joints"][names[static_cast<std::size_t>(i)]] = q[i];
    }
    j["spots"] = nlohmann::json::array();
    for (const auto& t : truth) {
      nlohmann::json s{{"row", t.row}, {"col", t.col}, {"visible", t.visible}};
      if (t.hidden_by_arm) s["hidden_by_arm"] = true;
      if (t.on_arm) s["on_arm"] = true;
      if (t.visible) {
        s["u"] = t.uv.x();
        s["v"] = t.uv.y();
        s["depth_m"] = t.depth_m;
        s["blur_px"] = t.blur_px;
        s["resolved"] = t.resolved;
      }
      j["spots"].push_back(s);
    }
    common::write_output_file(truth_file, j.dump(1) + "\n", "truth");
  }
  std::printf("%s: %s pose, %d of %zu spots visible -> %s\n", scenario.name.c_str(), pose_spec.c_str(), visible,
              truth.size(), out_png.c_str());
  return 0;
}

int run_decode_sweep(const ScenarioArg& scenario, experiment::SweepOptions o) {
  const auto cell = sim::build_cell(scenario.load());
  if (o.projector)
    calibration::check_projector_against_pattern(*o.projector, cell->projector->pattern(), cell->scenario.projector.pattern);
  const auto t0 = std::chrono::steady_clock::now();
  const experiment::SweepSummary s = experiment::run_decode_sweep(*cell, o);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("%s: %d poses (noise sigma", cell->scenario.name.c_str(), o.poses);
  for (double n : o.noise_sigmas) std::printf(" %.1f", n);
  std::printf(") in %.1f s\n", secs);
  std::printf("  decoded %d of %d visible (mean rate %.1f %%, worst pose %.1f %%), wrong ids %d, mislocated %d, "
              "partial %d (the named spot's light, its centre elsewhere or hidden; %d with its four pattern "
              "neighbours named, the most --interior-points lets into the law)\n",
              s.total_decoded, s.total_visible, 100 * s.mean_rate, 100 * s.min_rate, s.total_wrong,
              s.total_mislocated, s.total_partial, s.total_partial_interior);
  std::printf("  off their epipolar lines (%s), kept from the control law: %d ids (%d of the partial, %d of the "
              "mislocated, %d right, %d wrong)\n",
              o.projector ? "the calibration's" : "fitted to each frame's spots", s.total_off_line,
              s.total_off_line_partial, s.total_off_line_mislocated, s.total_off_line_right, s.total_off_line_wrong);
  std::printf("  reaching the control law (on their lines, their ids among the %d the servo names at the desired "
              "pose, s*): %d ids (%d right, %d mislocated, %d partial, %d wrong)\n",
              s.taught, s.total_to_law, s.total_to_law_right, s.total_to_law_mislocated, s.total_to_law_partial,
              s.total_to_law_wrong);
  if (o.projector && o.taught_points)
    std::printf("  held to their taught points: %d more ids kept from the law (%d right, %d mislocated, %d partial, "
                "%d wrong)\n",
                s.total_off_taught, s.total_off_taught_right, s.total_off_taught_mislocated, s.total_off_taught_partial,
                s.total_off_taught_wrong);
  std::printf("  against the decodable spots (visible, in a fully visible 3 x 3 window): %d of %d identified "
              "(mean rate %.1f %%); against all visible: %d of %d\n",
              s.total_correct_decodable, s.total_decodable, 100 * s.mean_decodable_rate, s.total_correct,
              s.total_visible);
  std::printf("  against the readable spots (resolved: not washed out by the projector's defocus; in a fully "
              "resolved 3 x 3 window): %d of %d identified (mean rate %.1f %%); %d of the %d visible spots are "
              "resolved\n",
              s.total_correct_readable, s.total_readable, 100 * s.mean_readable_rate, s.total_resolved,
              s.total_visible);
  std::printf("  against the readable spots on one object (a fully resolved 3 x 3 window all on one object; one "
              "across a silhouette shows no lattice in the image): %d of %d identified (mean rate %.1f %%)\n",
              s.total_correct_readable_one_object, s.total_readable_one_object, 100 * s.mean_readable_one_object_rate);
  std::printf("  against the readable spots apart in the image (no other visible spot's disc overlaps theirs; "
              "towards a silhouette the columns crowd together and the camera merges them): %d of %d identified "
              "(mean rate %.1f %%)\n",
              s.total_correct_readable_apart, s.total_readable_apart, 100 * s.mean_readable_apart_rate);
  std::printf("  where the readable spots are lost: %d segmented (a blob of their colour), %d with their four "
              "links right, %d with their whole window right after the graph check, %d identified\n",
              s.total_readable_segmented, s.total_readable_linked, s.total_readable_windowed,
              s.total_correct_readable);
  std::printf("  why the segmented readable spots without an id have none:");
  for (int c = 0; c < experiment::kLossCauses; ++c)
    if (s.total_lost[c] > 0) std::printf(" %s %d", experiment::kLossCauseNames[c] + 5, s.total_lost[c]);  // less "lost_"
  std::printf("\n  decode time median %.2f ms, p99 %.2f ms\n", s.median_ms, s.p99_ms);
  if (!o.out_dir.empty()) std::printf("  per-pose table: %s\n", (o.out_dir / "sweep.csv").c_str());
  return s.total_wrong == 0 ? common::exit_code::kDone : common::exit_code::kWrongIds;
}

struct LawFlags {
  std::string model = "desired-constant-depth";
  double z_hat = 0;  // 0: the scenario's desired distance
  double gain = 0.5;
  std::vector<double> adaptive;  // l0 linf slope
  double converge_mm = 1e3 * control::ControlLawOptions{}.convergence_translation_m;
  double converge_deg = control::ControlLawOptions{}.convergence_rotation_rad * 180 / 3.14159265358979323846;
  bool epipolar = false, fitted_lines = false;
  int points = 0;
  bool interior = false, taught_points = false;
  std::string robust = "none";
  std::string features;  // empty: the scenario's (points; plane for a projector on the camera)

  void add(CLI::App* c) {
    add_visual_features(c);
    c->add_option("--points", points,
                  "servo on this many points, chosen at teaching for the best-conditioned interaction matrix "
                  "(0: all)")
        ->check(CLI::Range(0, 4096))
        ->capture_default_str();
    add_interior(c);
    add_taught_points(c);
    add_fitted_lines(c);
    c->add_flag("--epipolar", epipolar,
                "decode with the projector's calibration (epipolar check and the grown lattice), as `servo run "
                "--projector` does");
    c->add_option("--model", model, "desired-constant-depth | desired | current | mean")->capture_default_str();
    c->add_option("--robust", robust, "tukey | huber | none: M-estimator weights on the points against wrong matches")
        ->capture_default_str();
    c->add_option("--z-hat", z_hat, "depth of desired-constant-depth (m); default: the mean depth of the lit spots "
                                    "at the desired pose, from the simulator (the paper's runs pass 0.9 or 0.6)")
        ->check(common::finite_in(0, 100));
    c->add_option("--gain", gain, "constant gain lambda")->capture_default_str()->check(common::finite_in(1e-9, 1e3));
    c->add_option("--gain-adaptive", adaptive, "adaptive gain: lambda0 lambda_inf slope0")
        ->expected(3)
        ->check(common::finite_in(0, 1e3));
    c->add_option("--converge-mm", converge_mm, "task-function translation that counts as converged (mm)")
        ->capture_default_str()
        ->check(common::finite_in(1e-9, 1e4));
    c->add_option("--converge-deg", converge_deg, "task-function rotation that counts as converged (deg)")
        ->capture_default_str()
        ->check(common::finite_in(1e-9, 180));
  }
  void apply(servo::ServoConfig& cfg, double default_z_hat) const {
    cfg.law.model = control::parse_interaction_model(model);
    cfg.law.z_hat_m = z_hat > 0 ? z_hat : default_z_hat;
    cfg.law.gain = adaptive.size() == 3 ? control::Gain{adaptive[0], adaptive[1], adaptive[2]} : control::Gain{gain, gain, 0};
    cfg.law.convergence_translation_m = converge_mm / 1e3;
    cfg.law.convergence_rotation_rad = converge_deg * 3.14159265358979323846 / 180;
    cfg.decoder.epipolar.enabled = epipolar;
    cfg.decoder.epipolar.fitted_lines = fitted_lines;
    cfg.points = points;
    cfg.interior_points = interior;
    cfg.taught_points = taught_points;
    cfg.law.robust = control::parse_robust_estimator(robust);
    cfg.law.features = experiment::visual_features_or_default(features, cfg);
  }
  void add_interior(CLI::App* c) {
    c->add_flag("--interior-points", interior,
                "servo on the interior of the matched spots: those whose four pattern neighbours are matched too, "
                "when they are at least half of them (docs/results.md)");
  }
  void add_taught_points(CLI::App* c) {
    c->add_flag("--taught-points", taught_points,
                "with --epipolar: hold each id to the point its spot lit at teaching; a spot away from it is no "
                "feature (docs/decoding.md)");
  }
  void add_fitted_lines(CLI::App* c) {
    c->add_flag("--fitted-lines", fitted_lines,
                "without --epipolar: decode each frame again on the epipolar lines fitted to its first decoding's "
                "spots, as with a calibration (docs/decoding.md; servo config key fitted_lines)");
  }
  // campaign and study add the law's flags one by one; this one they share with experiment
  void add_visual_features(CLI::App* c) {
    c->add_option("--visual-features", features,
                  "what the law servoes on: points (every decoded spot's x, y: the paper) | moments (the six image "
                  "moments of the matched spots) | surface (the plane of the triangulated spots, its normal and "
                  "distance, and three moments) | plane (its normal and distance alone: three degrees of freedom, "
                  "for a projector on the camera); default: points, plane with the projector on the camera; "
                  "docs/results.md")
        ->check(CLI::IsMember({"points", "moments", "surface", "plane"}));
  }
};

// where the law's points come from (loop::FeatureSource)
constexpr const char* kFeaturesHelp =
    "decoded | ideal (the simulator's true image positions of every visible spot) | resolved (those of the visible "
    "spots the projector's defocus leaves apart: what a perfect decoder could name) | decoded-ids (the spots the "
    "decoder names, each at its id's true image position: which spots from the decoder, where from the truth)";

// The errors a real cell has (issue 13): settings on top of the scenario's errors: and latency:.
struct ConditionFlags {
  std::vector<std::string> errors, latencies;
  double divergence_ratio = 0;
  double outliers = 0;
  double losses = 0;
  bool white_frame = false;
  double white_frame_lead = 0;

  void add(CLI::App* c) {
    std::string names;
    for (const auto& n : sim::error_names()) names += " " + n;
    c->add_option("--error", errors,
                  "a calibration error the servo is told (repeatable), NAME=VALUE; names:" + names +
                      ", seed (of the drawn directions; default: the run's)");
    c->add_option("--latency", latencies,
                  "a delay of the loop (repeatable), NAME=VALUE; names: acquisition_frames processing_frames "
                  "actuation_s");
    c->add_option("--divergence-ratio", divergence_ratio,
                  "stop as diverging when |e| exceeds this x its first value (0: never)")
        ->check(CLI::Range(0.0, 1e6))
        ->capture_default_str();
    c->add_option("--outliers", outliers,
                  "swap the ids of this fraction of the spots at every frame (seeded; wrong matches for the robust "
                  "law, issue 19)")
        ->check(common::finite_in(0, 0.5))
        ->capture_default_str();
    c->add_option("--losses", losses,
                  "drop this fraction of the decoded spots at every frame (seeded; decoding losses, issue 44)")
        ->check(common::finite_in(0, 0.9))
        ->capture_default_str();
    c->add_flag("--white-frame", white_frame,
                "beside each pattern frame the camera takes the white reference frame (the projector casting white), "
                "and the servo decodes their ratio: the surface's albedo divided out (docs/decoding.md, Appearance)");
    c->add_option("--white-frame-lead", white_frame_lead,
                  "with --white-frame: the white frame is taken this share of a frame period before its pattern "
                  "frame, on the way the camera came (a real camera takes the two one after the other; 0: at one "
                  "pose)")
        ->check(common::finite_in(0, 1))
        ->capture_default_str();
  }
  // the white frame is a decoded run's: the truth's sources (ideal, resolved) take no image
  void check_white_frame(const std::string& source) const {
    if (white_frame && loop::from_truth_alone(experiment::parse_feature_source(source)))
      throw std::invalid_argument("--white-frame needs --features decoded or decoded-ids");
    if (white_frame_lead > 0 && !white_frame) throw std::invalid_argument("--white-frame-lead needs --white-frame");
  }
  sim::CalibrationErrors errors_for(const sim::Scenario& sc) const {
    sim::CalibrationErrors e = sc.errors;
    for (const auto& a : errors) sim::set_error(e, a);
    return e;
  }
  sim::Latency latency_for(const sim::Scenario& sc) const {
    sim::Latency l = sc.latency;
    for (const auto& a : latencies) sim::set_latency(l, a);
    return l;
  }
};

using experiment::desired_depth;

// What `campaign` and `study` share: the draw of initial poses, the models, the law, the
// errors and delays.
struct CampaignFlags {
  experiment::CampaignOptions o;
  std::string models = "desired-constant-depth,desired,current,mean", source = "decoded", dir;
  LawFlags law;
  ConditionFlags conditions;
  bool no_plot = false;

  void add(CLI::App* c) {
    c->add_option("--runs", o.runs, "initial poses per model")->capture_default_str()->check(CLI::Range(1, 1000000));
    c->add_option("--models", models, "comma-separated models")->capture_default_str();
    c->add_option("--seed", o.seed, "seed of the initial-pose draw")->capture_default_str()->check(common::whole_number());
    c->add_option("--scale", o.scale, "initial offsets drawn in [-scale, scale] x the scenario's")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 100.0));
    c->add_option("--max-iterations", o.max_iterations, "iteration cap per run")
        ->capture_default_str()
        ->check(CLI::Range(1, 1000000));
    c->add_option("--features", source, kFeaturesHelp)->capture_default_str();
    c->add_option("--threads", o.threads, "worker threads")->capture_default_str()->check(CLI::Range(1, 256));
    c->add_option("-o,--output", dir, "output folder");
    c->add_option("--z-hat", law.z_hat, "depth of desired-constant-depth (m)")->check(common::finite_in(0, 100));
    c->add_option("--gain", law.gain, "constant gain")->capture_default_str()->check(common::finite_in(1e-9, 1e3));
    c->add_option("--points", law.points, "servo on this many best-conditioned points (0: all)")
        ->check(CLI::Range(0, 4096))
        ->capture_default_str();
    law.add_interior(c);
    law.add_taught_points(c);
    law.add_fitted_lines(c);
    c->add_flag("--epipolar", law.epipolar, "decode with the projector's calibration");
    c->add_option("--robust", law.robust, "tukey | huber | none: M-estimator weights on the points")->capture_default_str();
    law.add_visual_features(c);
    c->add_flag("--no-plot", no_plot, "do not draw the plots");
    conditions.add(c);
  }
  experiment::CampaignOptions options(const sim::Cell& cell) const {
    conditions.check_white_frame(source);
    experiment::CampaignOptions c = o;
    c.source = experiment::parse_feature_source(source);
    c.base = experiment::servo_config_for(cell);
    law.apply(c.base, desired_depth(cell));
    for (std::size_t a = 0, b; a < models.size(); a = b + 1) {
      b = models.find(',', a);
      if (b == std::string::npos) b = models.size();
      c.models.push_back(control::parse_interaction_model(models.substr(a, b - a)));
    }
    c.out_dir = dir;
    c.errors = conditions.errors_for(cell.scenario);
    c.latency = conditions.latency_for(cell.scenario);
    c.divergence_ratio = conditions.divergence_ratio;
    c.outlier_fraction = conditions.outliers;
    c.loss_fraction = conditions.losses;
    c.white_frame = conditions.white_frame;
    c.white_frame_lead = conditions.white_frame_lead;
    return c;
  }
};

// --record "": refused, not taken as "no recording"
const CLI::Validator non_empty_file(
    [](std::string& v) { return v.empty() ? std::string("an empty file name (name the MCAP file to write)") : std::string(); },
    "FILE");

int run_experiment_cli(const ScenarioArg& scenario, const LawFlags& law, const ConditionFlags& conditions,
                       const std::string& source, int max_iterations, const std::string& initial,
                       const std::string& out_dir, bool plot, const cell_record::RecordOptions& record) {
  const auto cell = sim::build_cell(scenario.load());
  experiment::ExperimentOptions o;
  o.errors = conditions.errors_for(cell->scenario);
  o.latency = conditions.latency_for(cell->scenario);
  o.outlier_fraction = conditions.outliers;
  o.loss_fraction = conditions.losses;
  o.white_frame = conditions.white_frame;
  o.white_frame_lead = conditions.white_frame_lead;
  o.servo = experiment::servo_config_for(*cell);
  o.servo.divergence_ratio = conditions.divergence_ratio;
  law.apply(o.servo, desired_depth(*cell));
  o.source = experiment::parse_feature_source(source);
  o.max_iterations = max_iterations;
  if (!initial.empty()) o.initial = sim::resolve_pose(cell->scenario, initial);
  o.out_dir = out_dir;
  std::unique_ptr<cellsim::ExperimentRecording> recording;
  if (!record.file.empty() && o.source == loop::FeatureSource::kDecodedIds)
    throw std::invalid_argument("--record: a run with --features decoded-ids has no wire form (a replay decodes the "
                                "images; the servo stepped on the truth)");
  if (!record.file.empty()) {
    recording = std::make_unique<cellsim::ExperimentRecording>(
        *cell, record,
        mcap::KeyValues{{"scenario", cell->scenario.name},
                        {"scenario_file", scenario.file},
                        {"seed", std::to_string(cell->scenario.seed)},
                        {"timing", "in-process (cellsim experiment): log and publish times are simulated time"},
                        {"model", law.model},
                        {"features", source},
                        {"images", record.images ? "recorded" : "left out (--record-no-images)"}});
    o.tap = recording.get();
  }
  o.progress = true;
  const auto r = experiment::run_experiment(*cell, o);
  std::printf("%s, model %s (z-hat %.3f m), %s features%s, visual features %s\n", cell->scenario.name.c_str(),
              law.model.c_str(), o.servo.law.z_hat_m, experiment::to_string(o.source).c_str(),
              loop::from_truth_alone(o.source)                   ? " (simulator truth)"
              : o.source == loop::FeatureSource::kDecodedIds ? " (at their true image positions)"
                                                             : "",
              control::to_string(o.servo.law.features).c_str());
  std::printf("  decoded: %d at the desired pose, %d at the initial pose\n", r.decoded_desired, r.decoded_initial);
  const std::string conds = sim::describe(*o.errors, *o.latency);
  if (conds != "none") std::printf("  errors and delays: %s\n", conds.c_str());
  const bool ran = r.ending != experiment::RunEnding::kNotTaught && r.ending != experiment::RunEnding::kRefused;
  if (ran)
    std::printf("  %s after %d iterations (%.2f s simulated)\n", r.stop_reason.c_str(), r.iterations,
                r.iterations * cell->scenario.dt_s);
  else
    std::printf("  %s: no run\n", r.stop_reason.c_str());
  if (ran)
    std::printf("  final error: %.3f mm, %.4f deg%s\n", 1e3 * r.final_translation_error_m, r.final_rotation_error_deg,
                cell->goal_plane ? " (to the plane its spots light: distance, attitude)" : "");
  if (ran && r.straight_line_m > 0)
    std::printf("  path: %.1f mm for %.1f mm away (%.2fx the straight line); condition of L: median %.3g, largest %.3g\n",
                1e3 * r.path_length_m, 1e3 * r.straight_line_m, r.path_length_m / r.straight_line_m, r.condition_median,
                r.condition_max);
  if (ran && o.source == loop::FeatureSource::kDecoded)
    std::printf("  features off their spot's centre (over 2 px from it or hidden, the simulator's truth) that the law "
                "took: %lld over the run, at most %d in one iteration\n",
                r.off_centre_total, r.off_centre_max);
  if (!out_dir.empty() && ran) {
    // the plots are named only when they were drawn (--no-plot, or no Python: none)
    const bool plotted = plot && experiment::plot_experiment(
                                     out_dir, cell->scenario.name + ", " + law.model + (law.interior ? ", interior points" : ""));
    std::printf("  trace: %s/trace.csv, features: %s/features.jsonl", out_dir.c_str(), out_dir.c_str());
    if (plotted)
      std::printf(", plots: %s/velocities.png %s/error_norm.png %s/pose_error.png", out_dir.c_str(), out_dir.c_str(),
                  out_dir.c_str());
    if (plotted && std::filesystem::exists(std::filesystem::path(out_dir) / "fig4.png"))
      std::printf(" %s/fig4.png", out_dir.c_str());
    std::printf("\n");
  }
  if (recording) std::printf("  recorded %s\n", recording->close().c_str());
  return exit_code_of(r.ending);
}

// One struct per subcommand: its flags, and what it runs once they are parsed.
struct RenderCommand {
  ScenarioArg scenario;
  std::string pose = "desired", out, truth, white;
  std::uint64_t frame = 0;
  std::vector<double> observer;
  CLI::App* add(CLI::App& app) {
    auto* c = app.add_subcommand("render", "render one camera frame of a scenario");
    scenario.add(c);
    c->add_option("--pose", pose,
                  "desired | initial | \"x y z rx ry rz\": offset from the desired pose, cm and deg, as the "
                  "scenario's initial_offset is: translation along the axes of its offset frame (the desired camera "
                  "axes turned by initial_offset.frame_rotation_deg; on plane, cylinder and ham Z points back from "
                  "the wall), then rotations about the moved X, Y, Z")
        ->capture_default_str();
    c->add_option("-o,--output", out, "PNG image to write")->required();
    c->add_option("--truth", truth, "ground-truth JSON to write");
    c->add_option("--white", white,
                  "PNG to write the white reference frame to: the same pose, the projector casting white wherever "
                  "its spots can reach (`servo decode --white` divides the surface's albedo out with it)");
    c->add_option("--frame", frame, "frame index (selects the noise draw)")->capture_default_str();
    c->add_option("--observer", observer,
                  "render from an observer camera instead (eye x y z, target x y z, metres): the arm in view")
        ->expected(6)
        ->check(CLI::Range(-100.0, 100.0));
    return c;
  }
  int run() const { return run_render(scenario, pose, out, truth, frame, observer, white); }
};

struct DecodeSweepCommand {
  ScenarioArg scenario;
  std::string dir, projector;
  experiment::SweepOptions sweep;
  bool tolerant = false, no_grow = false, no_two_votes = false, no_edge_runs = false;
  std::vector<std::string> decoder_options;
  CLI::App* add(CLI::App& app) {
    auto* c = app.add_subcommand("decode-sweep", "decoder accuracy against the ground truth over random poses");
    scenario.add(c);
    c->add_option("--poses", sweep.poses, "random poses")->capture_default_str()->check(CLI::PositiveNumber);
    c->add_option("--seed", sweep.seed, "seed of the pose draw and the noise")->capture_default_str()->check(common::whole_number());
    c->add_option("--noise", sweep.noise_sigmas, "sensor noise sigmas to cycle through (8-bit units)");
    c->add_option("--min-votes", sweep.decoder.min_votes, "windows that must name a spot")->capture_default_str();
    c->add_option("--min-island", sweep.decoder.min_island, "smallest island of decoded spots kept (0: off)")
        ->capture_default_str();
    c->add_flag("--tolerant", tolerant, "error-tolerant window reading");
    c->add_option("--projector", projector,
                  "projector calibration (YAML, from `cellsim calibration`): check ids along the epipolar lines "
                  "and grow the identified lattice");
    c->add_option("--epipolar-px", sweep.decoder.epipolar.tolerance_px,
                  "with --projector: how far (px) a spot may lie from its id's epipolar line")
        ->capture_default_str()
        ->check(CLI::Range(0.01, 100.0));
    c->add_option("--segment-length", sweep.decoder.epipolar.segment_length,
                  "with --projector: spots in a 1 x N row or column reading, decoder step 3b (under 3: off)")
        ->capture_default_str()
        ->check(CLI::Range(0, 15));
    c->add_option("--propagate-sources", sweep.decoder.epipolar.min_sources,
                  "with --projector: identified spots that must predict a grown spot's id (step 6)")
        ->capture_default_str()
        ->check(CLI::Range(1, 4));
    c->add_flag("--no-two-votes", no_two_votes,
                "with --projector: a spot needs --min-votes windows even when its two votes are both exact");
    c->add_flag("--no-grow", no_grow, "with --projector: do not grow the identified lattice where links are missing (step 6)");
    c->add_flag("--no-edge-runs", no_edge_runs,
                "with --projector: do not name the runs of foreshortened spots beyond an identified line (step 7)");
    c->add_flag("--fitted-lines", sweep.decoder.epipolar.fitted_lines,
                "without --projector: decode each frame again on the epipolar lines fitted to its first decoding's "
                "spots, as with a calibration (docs/decoding.md)");
    c->add_option("--crosstalk", sweep.told_crosstalk,
                  "with --projector: the camera crosstalk the decoder is told (default: the scenario camera's; "
                  "another value is a crosstalk calibration that far off)")
        ->check(common::finite_in(0, vision::kMaxCrosstalk));
    c->add_flag("--taught-points", sweep.taught_points,
                "with --projector: hold each id to the point it lit at the desired pose, as `servo run "
                "--taught-points` does (those away from it do not reach the law)");
    c->add_flag("--white-frame", sweep.white_frame,
                "beside each pattern frame take the white reference frame at the same pose (the projector casting "
                "white) and decode their ratio: the surface's albedo divided out (docs/decoding.md)");
    c->add_option("--threads", sweep.threads, "worker threads")->capture_default_str();
    c->add_option("--max-translation-cm", sweep.max_translation_cm,
                  "draw each translation component in +-this (default: the scenario's initial offset per axis)")
        ->check(common::finite_in(0, 100));
    c->add_option("--max-rotation-deg", sweep.max_rotation_deg,
                  "draw each rotation component in +-this (default: the scenario's initial offset per axis)")
        ->check(common::finite_in(0, 90));
    std::string names;
    for (const std::string& n : vision::decoder_option_names()) names += (names.empty() ? "" : ", ") + n;
    c->add_option("--decoder-option", decoder_options,
                  "NAME=VALUE: one of the decoder's numbers for this sweep (repeatable; docs/decoding.md says what "
                  "each does): " + names);
    c->add_option("-o,--output", dir, "folder for sweep.csv, wrong_ids.csv, spills.csv and overlays of poses with wrong ids");
    return c;
  }
  int run() {
    for (const std::string& a : decoder_options) vision::set_decoder_option(sweep.decoder, a);
    sweep.decoder.tolerance.enabled = tolerant;
    sweep.out_dir = dir;
    sweep.decoder.epipolar.two_exact_votes = !no_two_votes;
    sweep.decoder.epipolar.grow = !no_grow;
    sweep.decoder.epipolar.edge_runs = !no_edge_runs;
    if (!projector.empty()) sweep.projector = calibration::load_projector_calibration(projector);
    return run_decode_sweep(scenario, sweep);
  }
};

// The renderer's threads (issue 22): its rows shared out over OpenCV's pool, every core by
// default (in lockstep the servo waits while a frame renders); 1 keeps it to one core.
void add_render_threads(CLI::App* c, int& threads) {
  c->add_option("--render-threads", threads, "threads that render each frame (0: every core)")
      ->capture_default_str()
      ->check(CLI::Range(0, 256));
}
void use_render_threads(int threads) {
  if (threads > 0) cv::setNumThreads(threads);
}

struct ExperimentCommand {
  ScenarioArg scenario;
  std::string source = "decoded", initial, dir;
  cell_record::RecordOptions record;
  bool no_images = false;
  LawFlags law;
  ConditionFlags conditions;
  int max_iterations = 400;
  bool no_plot = false;
  int render_threads = 0;
  CLI::App* add(CLI::App& app) {
    auto* c =
        app.add_subcommand("experiment", "teach at the desired pose, start at the initial pose, servo (in-process)");
    scenario.add(c);
    law.add(c);
    c->add_option("--features", source, kFeaturesHelp)->capture_default_str();
    c->add_option("--max-iterations", max_iterations, "iteration cap")->capture_default_str()->check(CLI::PositiveNumber);
    c->add_option("--initial", initial, "initial pose instead of the scenario's: \"x y z rx ry rz\" (cm, deg)");
    c->add_option("-o,--output", dir, "folder for trace.csv, features.jsonl and the plots");
    c->add_flag("--no-plot", no_plot, "do not draw the plots");
    conditions.add(c);
    c->add_option("--record", record.file,
                  "record the run as cellsim serve --record would, into this MCAP file (simulated time; never "
                  "over a file that exists: written as FILE.partial, renamed when the run ends)")
        ->check(non_empty_file);
    c->add_flag("--record-no-images", no_images, "leave the camera images out of the recording");
    add_render_threads(c, render_threads);
    return c;
  }
  int run() {
    use_render_threads(render_threads);
    record.images = !no_images;
    if (no_images && record.file.empty()) throw std::invalid_argument("--record-no-images needs --record FILE.mcap");
    conditions.check_white_frame(source);
    return run_experiment_cli(scenario, law, conditions, source, max_iterations, initial, dir, !no_plot, record);
  }
};

struct Fig5SearchCommand {
  ScenarioArg scenario;
  experiment::DivergenceSearchOptions search;
  bool keep_spots = false;
  CLI::App* add(CLI::App& app) {
    auto* c = app.add_subcommand("fig5-search",
                                 "seeded search for a Fig. 5 configuration: five spots and an initial pose for which "
                                 "L(s*, Z-hat) diverges and L(s*, Z*), L(s, Z) converge (ideal features)");
    scenario.add(c, "scenario YAML file (the cylinder, projector and desired pose)");
    c->add_option("--tries", search.tries, "configurations drawn")->capture_default_str()->check(CLI::Range(1, 100000));
    c->add_option("--seed", search.seed, "seed of the draw")->capture_default_str()->check(common::whole_number());
    c->add_option("--z-hat", search.z_hat_m, "depth of the constant-depth model (m)")
        ->capture_default_str()
        ->check(CLI::Range(0.01, 100.0));
    c->add_option("--gain", search.gain, "constant gain")->capture_default_str()->check(CLI::Range(1e-6, 100.0));
    c->add_option("--max-iterations", search.max_iterations, "iteration cap per run")
        ->capture_default_str()
        ->check(CLI::Range(1, 100000));
    c->add_option("--max-translation-cm", search.max_translation_cm, "offset per axis in [-this, this] (cm)")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 200.0));
    c->add_option("--max-tilt-deg", search.max_tilt_deg, "rotation about x and y in [-this, this] (deg)")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 180.0));
    c->add_option("--max-roll-deg", search.max_roll_deg, "rotation about the optical axis in [-this, this] (deg)")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 180.0));
    c->add_flag("--keep-spots", keep_spots, "keep the scenario's only_spots (draw only the initial pose)");
    c->add_option("--threads", search.threads, "worker threads")->capture_default_str()->check(CLI::Range(1, 64));
    c->add_option("-o,--output", search.out_dir, "folder for candidates.csv and best.yaml");
    return c;
  }
  int run() {
    search.vary_spots = !keep_spots;
    const sim::ResolvedScenario sc = scenario.load();
    const auto r = experiment::search_divergence(sc, search);
    int kept = 0;
    for (const auto& c : r.candidates) kept += c.kept;
    std::printf("%s: %d of %d configurations kept (L(s*, Z-hat = %.2f) diverges, L(s*, Z*) converges, L(s, Z) "
                "converges faster)\n",
                sc.name.c_str(), kept, search.tries, search.z_hat_m);
    if (r.best < 0) return common::exit_code::kNoneFound;
    const auto& b = r.candidates[static_cast<std::size_t>(r.best)];
    std::printf("  least displaced: try %d, spots", b.index);
    for (const auto& rc : b.spots) std::printf(" (%d, %d)", rc[0], rc[1]);
    std::printf(", offset %.2f %.2f %.2f cm, %.2f %.2f %.2f deg\n", b.offset[0], b.offset[1], b.offset[2], b.offset[3],
                b.offset[4], b.offset[5]);
    std::printf("  constant depth: %s after %d; desired: converged in %d; current: converged in %d\n",
                b.constant_depth.stop_reason.c_str(), b.constant_depth.iterations, b.desired.iterations,
                b.current.iterations);
    if (!search.out_dir.empty())
      std::printf("  %s/candidates.csv, %s/best.yaml\n", search.out_dir.c_str(), search.out_dir.c_str());
    return 0;
  }
};

// "I/N": digits only, at most six each (sscanf's %d wrapped 1/4294967297 to 1/1, issue 18)
std::pair<int, int> parse_shard(const std::string& shard) {
  const std::size_t slash = shard.find('/');
  const auto digits = [](const std::string& t) {
    return !t.empty() && t.size() <= 6 && t.find_first_not_of("0123456789") == std::string::npos;
  };
  const std::string is = slash == std::string::npos ? "" : shard.substr(0, slash),
                    ns = slash == std::string::npos ? "" : shard.substr(slash + 1);
  const int i = digits(is) ? std::stoi(is) : 0, n = digits(ns) ? std::stoi(ns) : 0;
  if (!digits(is) || !digits(ns) || n < 1 || n > 100000 || i < 1 || i > n)
    throw std::invalid_argument("--shard '" + common::printable(shard) + "': expected I/N with 1 <= I <= N <= 100000");
  return {i, n};
}

struct CampaignCommand {
  ScenarioArg scenario;
  std::string shard, merge_out;
  std::vector<std::string> merge_dirs;
  CampaignFlags flags;
  CLI::App* merge = nullptr;
  CLI::App* add(CLI::App& app) {
    auto* c = app.add_subcommand("campaign", "many random initial poses per interaction-matrix model");
    scenario.add(c, "scenario YAML file", false);
    c->add_option("--shard", shard,
                  "run slice I of N (I/N): every N-th initial pose; merge the slices with `campaign merge`");
    merge = c->add_subcommand("merge", "combine the folders of a sharded campaign into the unsharded result");
    merge->add_option("folders", merge_dirs, "the shards' output folders")->required();
    merge->add_option("-o,--output", merge_out, "folder for the merged campaign.csv and summary.md")->required();
    flags.add(c);
    return c;
  }
  int run() const {
    if (*merge) {
      std::vector<std::filesystem::path> dirs(merge_dirs.begin(), merge_dirs.end());
      std::printf("%s", experiment::merge_campaigns(dirs, merge_out).c_str());
      if (!flags.no_plot) experiment::plot_campaign(merge_out, "merged campaign");
      return 0;
    }
    if (scenario.file.empty()) throw std::invalid_argument("campaign: give a scenario file (or `campaign merge FOLDER...`)");
    if (flags.dir.empty()) throw std::invalid_argument("campaign: -o,--output FOLDER is required");
    const auto cell = sim::build_cell(scenario.load());
    experiment::CampaignOptions o = flags.options(*cell);
    if (!shard.empty()) std::tie(o.shard_index, o.shard_count) = parse_shard(shard);
    std::printf("%s", experiment::run_campaign(*cell, o).c_str());
    // the title says where the points came from when they are not the decoder's own
    const std::string from =
        o.source == loop::FeatureSource::kDecoded ? "" : ", " + experiment::to_string(o.source) + " features";
    if (!flags.no_plot) experiment::plot_campaign(flags.dir, cell->scenario.name + " campaign" + from);
    return 0;
  }
};

struct StudyCommand {
  ScenarioArg scenario;
  std::vector<std::string> axes;
  CampaignFlags flags;
  CLI::App* add(CLI::App& app) {
    auto* c = app.add_subcommand("study", "a campaign at every point of one or two axes (depth, errors, delays, gain)");
    scenario.add(c);
    std::string names;
    for (const auto& n : experiment::study_axis_names()) names += " " + n;
    c->add_option("--axis", axes, "NAME=V1,V2,... (once or twice: a grid); names:" + names)->required();
    flags.add(c);
    return c;
  }
  int run() const {
    experiment::StudyOptions so;
    for (const auto& a : axes) so.axes.push_back(experiment::parse_study_axis(a));
    if (so.axes.size() > 2) throw std::invalid_argument("study: at most two --axis");
    if (so.axes.size() == 2 && so.axes[0].name == so.axes[1].name)
      throw std::invalid_argument("study: --axis " + common::printable(so.axes[0].name) +
                                  " given twice (give its values once: NAME=V1,V2,...)");
    if (flags.dir.empty()) throw std::invalid_argument("study: -o,--output FOLDER is required");
    const sim::ResolvedScenario sc = scenario.load();
    const auto cell = sim::build_cell(sc);
    so.campaign = flags.options(*cell);
    so.out_dir = flags.dir;
    std::printf("%s", experiment::run_study(sc, so).c_str());
    if (!flags.no_plot) experiment::plot_study(flags.dir, sc.name + " study");
    return 0;
  }
};

struct ServeCommand {
  std::string scenario, mode = "lockstep", trace;
  bool no_images = false;
  int render_threads = 0;
  sim::ServiceOptions svc;
  cell_dds::DdsFlags dds;
  CLI::App* add(CLI::App& app) {
    auto* c = app.add_subcommand("serve", "run the simulated cell as a DDS service");
    c->add_option("scenario", scenario, "scenario YAML file")->required();
    c->add_option("--mode", mode, "lockstep | realtime")->capture_default_str();
    dds.add_to(*c);
    c->add_option("--watchdog-ms", svc.watchdog_ms, "stop the robot after this long without a valid twist")
        ->capture_default_str();
    c->add_option("--republish-ms", svc.republish_ms, "lockstep: send an unanswered frame again after this long")
        ->capture_default_str();
    c->add_flag("--autorun", svc.autorun, "teach, reset to the initial pose and start without an external client");
    c->add_option("--max-frames", svc.max_frames, "exit after this many frames")->capture_default_str();
    c->add_flag("--exit-on-converged", svc.exit_on_converged, "exit when the servo reports CONVERGED");
    c->add_flag("--exit-on-stop", svc.exit_on_stop,
                "also exit on any other stop of a run: the servo stopping itself (a lasting safe stop, a "
                "runaway) or the robot stopping (a collision); the summary line names it");
    c->add_option("--trace", trace, "folder for trace.csv");
    c->add_option("--scenarios", svc.scenarios_dir,
                  "the folder LOAD_SCENARIO may read scenarios from, links resolved (default: the served scenario's)");
    c->add_option("--record", svc.record,
                  "record every message on the wire into this MCAP file (ROS 2 profile: ros2 bag info, Foxglove, "
                  "servo replay; never over a file that exists: written as FILE.partial, renamed when the run ends)")
        ->check(non_empty_file);
    c->add_flag("--record-no-images", no_images, "leave the camera images out of the recording (long runs)");
    c->add_flag("--white-frame", svc.white_frame,
                "beside each frame publish the white reference frame (the projector casting white, the same pose, "
                "its own noise) on rt/camera/white/image_raw, with the frame's stamp and before it, for `servo run "
                "--white-frame` (docs/decoding.md, Appearance)");
    c->add_option("--white-frame-lead", svc.white_frame_lead,
                  "with --white-frame: the white frame is taken this share of a frame period before its frame, on the "
                  "way the camera came (a real camera takes the two one after the other; 0: at one pose)")
        ->check(common::finite_in(0, 1))
        ->capture_default_str();
    c->add_option("--foxglove", svc.foxglove_port,
                  "serve the run live in Foxglove on ws://127.0.0.1:PORT (its WebSocket protocol; 0: a free port, printed)");
    c->add_option("--foxglove-address", svc.foxglove_address,
                  "with --foxglove: the IPv4 address to listen on, in digits (default loopback: the run stays on this "
                  "machine; 0.0.0.0 opens it to the network, unauthenticated)")
        ->capture_default_str();
    add_render_threads(c, render_threads);
    return c;
  }
  int run() {
    use_render_threads(render_threads);
    svc.scenario = scenario;
    if (mode != "lockstep" && mode != "realtime") throw std::invalid_argument("--mode must be lockstep or realtime");
    common::require_within("--watchdog-ms", svc.watchdog_ms, 1, 60000);
    common::require_within("--republish-ms", svc.republish_ms, 1, 600000);
    common::require_within("--max-frames", static_cast<double>(svc.max_frames), 0, 1e12);
    common::require_within("--foxglove", svc.foxglove_port, -1, 65535);
    if (svc.foxglove_address != "127.0.0.1" && svc.foxglove_port < 0)
      throw std::invalid_argument("--foxglove-address needs --foxglove PORT");
    svc.mode = mode == "lockstep" ? sim::TimingMode::kLockstep : sim::TimingMode::kRealtime;
    dds.apply_to(svc);
    svc.trace_dir = trace;
    svc.record_images = !no_images;
    if (no_images && svc.record.empty()) throw std::invalid_argument("--record-no-images needs --record FILE.mcap");
    if (svc.white_frame_lead > 0 && !svc.white_frame)
      throw std::invalid_argument("--white-frame-lead needs --white-frame");
    return sim::run_sim_service(svc);
  }
};

// `cellsim bridge`: the cell's topics live in Foxglove (docs/topics.md, Live view)
struct BridgeCommand {
  cellsim::BridgeOptions o;
  cell_dds::DdsFlags dds;
  CLI::App* add(CLI::App& app) {
    auto* c = app.add_subcommand("bridge", "serve the cell's topics live to Foxglove (its WebSocket protocol, loopback)");
    dds.add_to(*c);
    c->add_option("--port", o.port, "TCP port (0: a free one, printed)")->capture_default_str();
    c->add_option("--address", o.address,
                  "the IPv4 address to listen on, in digits (default loopback: the cell stays on this machine; 0.0.0.0 "
                  "opens it to the network, unauthenticated)")
        ->capture_default_str();
    c->add_option("--seconds", o.seconds, "stop after this long (default: until Ctrl-C)");
    return c;
  }
  int run() {
    common::require_within("--port", o.port, 0, 65535);
    common::require_within("--seconds", o.seconds, 0, 1e7);
    dds.apply_to(o);
    return cellsim::run_bridge(o);
  }
};

struct CalibrationCommand {
  ScenarioArg scenario;
  std::string out;
  CLI::App* add(CLI::App& app) {
    auto* c = app.add_subcommand("calibration", "write the projector calibration the servo triangulates with");
    scenario.add(c);
    c->add_option("-o,--output", out, "calibration YAML to write")->required();
    return c;
  }
  int run() const {
    const sim::ResolvedScenario s = scenario.load();
    const pattern::MArray a = pattern::read_marray(s.projector.pattern);
    const auto& k = s.projector.intrinsics;
    calibration::ProjectorModel m;
    m.fx = k.fx, m.fy = k.fy, m.cx = k.cx, m.cy = k.cy;
    m.spot_pitch_px = s.projector.spot_pitch_px;
    m.rows = a.rows, m.cols = a.cols;
    // what a calibration would give: off by the scenario's projector errors, if any
    m.world_T_projector = s.projector.world_T_projector * sim::scenario_errors(s).projector_delta;
    if (s.projector.on_camera) m.on_camera = *s.projector.on_camera * sim::scenario_errors(s).projector_delta;
    const bool off = s.errors.projector_position_mm > 0 || s.errors.projector_rotation_deg > 0;
    calibration::write_projector_calibration(m, out,
                                       "projector calibration of scenario " + s.name +
                                           (off ? " (with the scenario's projector errors: " +
                                                      sim::describe(s.errors, {}) + ")"
                                                : " (exact: the simulator's own)"));
    std::printf("wrote %s\n", out.c_str());
    return 0;
  }
};

}  // namespace

int main(int argc, char** argv) {
  // a write past a file-size limit (ulimit -f) fails with EFBIG, which the recorder handles as
  // a full disk; the signal's default would kill the run
  std::signal(SIGXFSZ, SIG_IGN);
  CLI::App app{"cellsim: simulator of a camera-projector robot cell"};
  common::plain_help(app);
  common::verbosity_flags(app);
  app.set_version_flag("--version", std::string("cellsim ") + CELL_VERSION);
  app.require_subcommand(1);
  RenderCommand render;
  DecodeSweepCommand sweep;
  ExperimentCommand experiment;
  Fig5SearchCommand fig5;
  CampaignCommand campaign;
  StudyCommand study;
  ServeCommand serve;
  BridgeCommand bridge;
  CalibrationCommand calibration;
  const common::Subcommands commands = {
      {render.add(app), [&] { return render.run(); }},
      {sweep.add(app), [&] { return sweep.run(); }},
      {experiment.add(app), [&] { return experiment.run(); }},
      {fig5.add(app), [&] { return fig5.run(); }},
      {campaign.add(app), [&] { return campaign.run(); }},
      {study.add(app), [&] { return study.run(); }},
      {serve.add(app), [&] { return serve.run(); }},
      {bridge.add(app), [&] { return bridge.run(); }},
      {calibration.add(app), [&] { return calibration.run(); }},
  };
  common::require_finite_numbers(app);
  if (const int rc = common::parse_command_line(app, argc, argv, "cellsim"); rc >= 0) return rc;
  return common::run_subcommand(commands, "cellsim");
}
