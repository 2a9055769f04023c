// The errors a real cell has, in the in-process loop (issue 13): calibration errors and
// delays change what the servo does, and with every one of them zero nothing changes, bit
// for bit.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <cstdint>
#include <cstdlib>
#include <sstream>

#include <unistd.h>

#include "sim/cell/build_cell.hpp"
#include "sim/experiment/experiment.hpp"
#include "support/numeric_text.hpp"

namespace {

const std::string kDir = std::string(CELL_SOURCE_DIR) + "/sim/scenarios/";

experiment::ExperimentOptions options(const sim::Cell& cell, control::InteractionModel model, loop::FeatureSource source,
                                   int cap) {
  experiment::ExperimentOptions o;
  o.servo = experiment::servo_config_for(cell);
  o.servo.law.model = model;
  o.servo.law.z_hat_m = 0.6;
  o.source = source;
  o.max_iterations = cap;
  return o;
}

bool same_trace(const experiment::ExperimentResult& a, const experiment::ExperimentResult& b) {
  if (a.trace.size() != b.trace.size()) return false;
  for (std::size_t k = 0; k < a.trace.size(); ++k) {
    const auto &x = a.trace[k], &y = b.trace[k];
    // exact comparisons: bit for bit
    if (x.twist != y.twist || x.error_norm != y.error_norm || x.translation_error_m != y.translation_error_m ||
        x.rotation_error_deg != y.rotation_error_deg || x.decoded != y.decoded || x.matched != y.matched ||
        x.robot_limits != y.robot_limits)
      return false;
  }
  return a.stop_reason == b.stop_reason && a.final_translation_error_m == b.final_translation_error_m;
}

std::string read(const std::filesystem::path& p) {
  std::ifstream f(p);
  return {std::istreambuf_iterator<char>(f), {}};
}

// Every error and delay set to zero, in the options and in the scenario file, gives the run
// of a scenario that has none: the decoded arm on the cylinder, and the ideal fig5.
TEST(CellErrorsLoop, ZeroErrorsAndDelaysChangeNothingBitForBit) {
  const auto cell = sim::build_cell(sim::load_scenario(kDir + "cylinder.yaml"));
  auto o = options(*cell, control::InteractionModel::kDesiredConstantDepth, loop::FeatureSource::kDecoded, 25);
  const auto plain = experiment::run_experiment(*cell, o);
  o.errors = sim::CalibrationErrors{};
  o.errors->seed = 77;  // a seed alone draws nothing
  o.latency = sim::Latency{};
  EXPECT_TRUE(same_trace(plain, experiment::run_experiment(*cell, o)));

  // the same zeros written in a scenario file
  std::string text = read(kDir + "fig5.yaml");
  for (std::size_t p; (p = text.find("../../")) != std::string::npos;) text.replace(p, 6, std::string(CELL_SOURCE_DIR) + "/");
  std::string zeros = "errors:\n";
  for (const auto& n : sim::error_names()) zeros += "  " + n + ": 0\n";
  zeros += "latency: {acquisition_frames: 0, processing_frames: 0, actuation_s: 0}\n";
  const auto file = std::filesystem::temp_directory_path() / "_test_fig5_zero_errors.yaml";
  std::ofstream(file) << text << zeros;
  const auto zero_cell = sim::build_cell(sim::load_scenario(file));
  std::filesystem::remove(file);
  const auto fig5 = sim::build_cell(sim::load_scenario(kDir + "fig5.yaml"));
  const auto a = experiment::run_experiment(*fig5, options(*fig5, control::InteractionModel::kCurrent, loop::FeatureSource::kIdeal, 400));
  const auto b = experiment::run_experiment(*zero_cell, options(*zero_cell, control::InteractionModel::kCurrent, loop::FeatureSource::kIdeal, 400));
  EXPECT_TRUE(a.converged) << a.stop_reason;
  EXPECT_TRUE(same_trace(a, b));
}

// Today's results: a run whose scenario did not change, as the code before the errors existed
// wrote it (`cellsim experiment sim/scenarios/cylinder.yaml --features ideal --model
// desired-constant-depth --z-hat 0.6 --max-iterations 60` at commit 22e97a6). Stored results
// are compared across machines within the stated tolerance (tests/support/numeric_text.hpp:
// 1e-6 relative), never bit for bit: another CPU rounds the last digit differently (issue 18,
// item 1). trace.csv is kept whole; features.jsonl (2 MB) as a per-line digest of its numbers.
// Bit-reproducibility on one machine is the next test's.
TEST(CellErrorsLoop, TracesEqualThoseBeforeTheErrorsExisted) {
  const auto cell = sim::build_cell(sim::load_scenario(kDir + "cylinder.yaml"));
  auto o = options(*cell, control::InteractionModel::kDesiredConstantDepth, loop::FeatureSource::kIdeal, 60);
  o.out_dir = std::filesystem::temp_directory_path() / ("_test_golden_cylinder_ideal_" + std::to_string(::getpid()));
  experiment::run_experiment(*cell, o);
  const std::string now = read(o.out_dir / "trace.csv"), features = read(o.out_dir / "features.jsonl");
  std::filesystem::remove_all(o.out_dir);
  const std::string golden = std::string(CELL_SOURCE_DIR) + "/tests/data/golden/";
  const std::string before = read(golden + "cylinder_ideal_60.csv");
  ASSERT_FALSE(before.empty());
  // the results, not the header's description of the run (it names more settings as they come)
  const auto results = [](const std::string& text) {
    std::istringstream in(text);
    std::string out;
    for (std::string line; std::getline(in, line);)
      if (line.rfind('#', 0) != 0) out += line + '\n';
    return out;
  };
  EXPECT_EQ(cell_test::numeric_difference(results(now), results(before)), "");
  // CELL_WRITE_GOLDEN=1 writes the digest anew (after a deliberate change of the results)
  if (std::getenv("CELL_WRITE_GOLDEN")) std::ofstream(golden + "cylinder_ideal_60_features.digest") << cell_test::numeric_digest(features);
  const std::string digest = read(golden + "cylinder_ideal_60_features.digest");
  ASSERT_FALSE(digest.empty());
  EXPECT_EQ(cell_test::digest_difference(cell_test::numeric_digest(features), digest), "");
}

// Lockstep's promise on one machine: the same run twice gives the same bits, trace and
// features alike.
TEST(CellErrorsLoop, TheSameRunTwiceGivesTheSameBits) {
  const auto cell = sim::build_cell(sim::load_scenario(kDir + "cylinder.yaml"));
  std::string trace[2], features[2];
  for (int k = 0; k < 2; ++k) {
    auto o = options(*cell, control::InteractionModel::kDesiredConstantDepth, loop::FeatureSource::kIdeal, 40);
    o.out_dir = std::filesystem::temp_directory_path() / ("_test_twice_" + std::to_string(::getpid()) + "_" + std::to_string(k));
    experiment::run_experiment(*cell, o);
    trace[k] = read(o.out_dir / "trace.csv");
    features[k] = read(o.out_dir / "features.jsonl");
    std::filesystem::remove_all(o.out_dir);
  }
  ASSERT_FALSE(trace[0].empty());
  EXPECT_EQ(trace[0], trace[1]);
  EXPECT_TRUE(features[0] == features[1]) << "features.jsonl differs between two identical runs";
}

// Calibration errors reach the servo and the robot: the path changes, and teach-by-showing
// still brings the true camera back to where it was taught (IBVS needs no exact calibration
// to converge near the goal; the campaign measures how far that goes).
TEST(CellErrorsLoop, CalibrationErrorsChangeThePathNotTheTaughtGoal) {
  const auto cell = sim::build_cell(sim::load_scenario(kDir + "fig5.yaml"));
  const auto exact = experiment::run_experiment(
      *cell, options(*cell, control::InteractionModel::kCurrent, loop::FeatureSource::kIdeal, 800));
  for (const char* which : {"focal_pct=5", "principal_point_px=10", "projector_position_mm=20", "hand_eye_rotation_deg=3"}) {
    auto o = options(*cell, control::InteractionModel::kCurrent, loop::FeatureSource::kIdeal, 800);
    o.errors = sim::CalibrationErrors{};
    sim::set_error(*o.errors, which);
    const auto r = experiment::run_experiment(*cell, o);
    EXPECT_FALSE(same_trace(exact, r)) << which << " changed nothing";
    EXPECT_TRUE(r.converged) << which << ": " << r.stop_reason;
    EXPECT_LT(r.final_translation_error_m, 2e-3) << which;
  }
}

// The arm's kinematic errors: the controller's model is off, the loop still converges, and
// the pose the robot reports is not the true one.
TEST(CellErrorsLoop, ArmKinematicErrorsChangeThePath) {
  const auto cell = sim::build_cell(sim::load_scenario(kDir + "cylinder.yaml"));
  auto o = options(*cell, control::InteractionModel::kDesiredConstantDepth, loop::FeatureSource::kIdeal, 700);
  const auto exact = experiment::run_experiment(*cell, o);
  o.errors = sim::CalibrationErrors{};
  o.errors->link_length_pct = 1;
  o.errors->joint_offset_deg = 0.5;
  const auto r = experiment::run_experiment(*cell, o);
  EXPECT_TRUE(exact.converged) << exact.stop_reason;
  EXPECT_FALSE(same_trace(exact, r));
  EXPECT_TRUE(r.converged) << r.stop_reason;
  EXPECT_LT(r.final_translation_error_m, 1e-3);
}

// Delays: the twist of frame k moves the robot at frame k + d, the image of frame k shows
// frame k - a, and an actuation delay holds the previous twist for part of the frame.
TEST(CellErrorsLoop, DelaysHoldTheRobotAndTheImageBack) {
  const auto cell = sim::build_cell(sim::load_scenario(kDir + "fig5.yaml"));
  const auto run = [&](const std::string& latency) {
    auto o = options(*cell, control::InteractionModel::kDesired, loop::FeatureSource::kIdeal, 40);
    o.latency = sim::Latency{};
    if (!latency.empty()) sim::set_latency(*o.latency, latency);
    return experiment::run_experiment(*cell, o);
  };
  const auto none = run(""), processing = run("processing_frames=3"), acquisition = run("acquisition_frames=2"),
             actuation = run("actuation_s=0.02");
  // processing: the robot stands still for 3 frames, then follows the twists 3 frames late
  for (int k = 1; k <= 3; ++k) EXPECT_EQ(processing.trace[k].translation_error_m, none.trace[0].translation_error_m);
  EXPECT_NE(processing.trace[4].translation_error_m, none.trace[0].translation_error_m);
  // acquisition: the robot moves at once, but the servo sees the first frame three times
  EXPECT_NE(acquisition.trace[1].translation_error_m, none.trace[0].translation_error_m);
  EXPECT_EQ(acquisition.trace[1].error_norm, none.trace[0].error_norm);
  EXPECT_EQ(acquisition.trace[2].error_norm, none.trace[0].error_norm);
  EXPECT_NE(acquisition.trace[3].error_norm, none.trace[0].error_norm);
  // actuation (half a frame): after one frame the camera moved about half as far
  const double moved_none = std::abs(none.trace[1].translation_error_m - none.trace[0].translation_error_m);
  const double moved_half = std::abs(actuation.trace[1].translation_error_m - actuation.trace[0].translation_error_m);
  EXPECT_NEAR(moved_half, 0.5 * moved_none, 0.1 * moved_none);
}

}  // namespace
