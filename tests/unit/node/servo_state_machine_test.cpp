// The servo's state machine on real rendered images and a fake clock: image and camera_info
// checks, teaching from the teach frame, convergence only on applied frames, LOST (issue 9).
#include "servo/node/servo_state_machine.hpp"

#include <gtest/gtest.h>

#include "sim/cell/build_cell.hpp"
#include "sim/render/renderer.hpp"

namespace servo {
namespace {

const std::string kScenarios = std::string(CELL_SOURCE_DIR) + "/sim/scenarios/";

struct Frames : ::testing::Test {
  std::unique_ptr<sim::Cell> cell = sim::build_cell(sim::load_scenario(kScenarios + "plane.yaml"));
  cv::Mat desired = sim::render_image(*cell, cell->scenario.world_T_desired, 1);
  cv::Mat initial = sim::render_image(*cell, cell->scenario.world_T_initial(), 2);

  std::unique_ptr<ServoStateMachine> make(bool autostart = false, double divergence_ratio = 0) {
    ServoConfig c;
    c.law.z_hat_m = 0.9;
    c.divergence_ratio = divergence_ratio;
    auto p = std::make_unique<ServoPipeline>(pattern::WindowTable(cell->projector->pattern(), {3, 3}), c);
    auto m = std::make_unique<ServoStateMachine>(std::move(p), ServoTiming{0.5, autostart});
    EXPECT_EQ(m->on_camera_info(info()), "");
    return m;
  }
  CameraInfoMsg info() const {
    const auto& k = cell->scenario.camera.intrinsics;
    const auto& d = cell->scenario.camera.distortion;
    return {static_cast<std::uint32_t>(k.width), static_cast<std::uint32_t>(k.height),
            {k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1}, std::vector<double>(d.begin(), d.end())};
  }
  static ImageView view(const cv::Mat& rgb, Stamp s) {
    return {s, "rgb8", static_cast<std::uint32_t>(rgb.cols), static_cast<std::uint32_t>(rgb.rows),
            static_cast<std::uint32_t>(rgb.cols * 3), 0, rgb.data, rgb.total() * 3};
  }
  static Stamp at(int frame) { return {0, static_cast<std::uint32_t>(frame * 40000000)}; }
};

// item 1: width 1431655766 (x 3 wraps to 2 in 32 bits) with a 2-byte image killed the servo
TEST_F(Frames, OverflowingImageHeaderIsRejectedWithAZeroTwist) {
  auto m = make();
  const std::uint8_t two[2] = {1, 2};
  ImageView v{at(0), "rgb8", 1431655766u, 1, 1431655766u * 3u, 0, two, 2};
  const ServoReply r = m->on_image(v, 0);
  EXPECT_TRUE(r.twist.isZero());
  EXPECT_NE(r.reason.find("rejected image"), std::string::npos) << r.reason;
  ImageView w{at(1), "rgb8", 640, 480, 1920, 0, two, 2};
  EXPECT_NE(m->on_image(w, 0).reason.find("2 bytes for 640 x 480"), std::string::npos);
  ImageView e{at(2), "bgr8\x01\xff", 640, 480, 1920, 0, desired.data, desired.total() * 3};
  const std::string reason = m->on_image(e, 0).reason;
  EXPECT_EQ(reason.find('\x01'), std::string::npos) << reason;
  EXPECT_EQ(m->rejected(), 3);
}

// Issue 41: a white reference frame beside the image is checked as the image is (its size
// against camera_info, its bytes against its header), and a good one is decoded with it.
TEST_F(Frames, AWhiteFrameIsCheckedAsTheImageIs) {
  auto m = make();
  const std::uint8_t two[2] = {1, 2};
  const ImageView small{at(0), "rgb8", 640, 480, 1920, 0, two, 2};
  const ServoReply r = m->on_image(view(desired, at(0)), 0, &small);
  EXPECT_EQ(r.reason.rfind("white frame: rejected image: 2 bytes for 640 x 480", 0), 0u) << r.reason;
  EXPECT_EQ(m->rejected(), 1);
  const cv::Mat white = sim::render_image(*cell, cell->scenario.world_T_desired, sim::white_frame_seed(1), nullptr,
                                          nullptr, nullptr, sim::Cast::kWhite);
  const ImageView w = view(white, at(1));
  m->on_command(static_cast<int>(cell_dds::SimCommand::kTeach));
  const ServoReply taught = m->on_image(view(desired, at(1)), 0, &w);
  EXPECT_TRUE(taught.taught) << taught.reason;
  EXPECT_EQ(m->rejected(), 1);
}

// A servo told to take white frames (servo run --white-frame) rejects an image that comes
// without one, or with one of another stamp (another frame's white), and names why.
TEST_F(Frames, AServoTakingWhiteFramesRejectsAnImageWithoutItsOwn) {
  ServoConfig c;
  c.law.z_hat_m = 0.9;
  c.white_frame = true;
  ServoStateMachine m(std::make_unique<ServoPipeline>(pattern::WindowTable(cell->projector->pattern(), {3, 3}), c),
                      ServoTiming{});
  ASSERT_EQ(m.on_camera_info(info()), "");
  m.on_command(static_cast<int>(cell_dds::SimCommand::kTeach));
  EXPECT_EQ(m.on_image(view(desired, at(0)), 0).reason,
            "rejected image: no white reference frame with its stamp (--white-frame)");
  const cv::Mat white = sim::render_image(*cell, cell->scenario.world_T_desired, sim::white_frame_seed(1), nullptr,
                                          nullptr, nullptr, sim::Cast::kWhite);
  const ImageView earlier = view(white, at(0));
  const ServoReply r = m.on_image(view(desired, at(1)), 0, &earlier);
  EXPECT_EQ(r.reason.rfind("white frame: rejected image: stamped 0.000000000 s, the image 0.040000000 s", 0), 0u) << r.reason;
  EXPECT_FALSE(r.taught);
  EXPECT_EQ(m.rejected(), 2);
  const ImageView own = view(white, at(2));
  EXPECT_TRUE(m.on_image(view(desired, at(2)), 0, &own).taught);
}

TEST_F(Frames, CameraInfoIsCheckedBeforeItIsUsed) {
  auto m = make();
  CameraInfoMsg bad = info();
  bad.k[0] = std::nan("");
  EXPECT_NE(m->on_camera_info(bad), "");
  bad = info();
  bad.width = 16384;
  bad.height = 16384;
  EXPECT_NE(m->on_camera_info(bad).find("limit"), std::string::npos);
  bad = info();
  bad.d.assign(1000, 0.0);
  EXPECT_NE(m->on_camera_info(bad), "");
  bad = info();
  bad.k[2] = 1e300;
  EXPECT_NE(m->on_camera_info(bad), "");
  // the good one stays in force
  m->on_command(static_cast<int>(cell_dds::SimCommand::kTeach));
  EXPECT_TRUE(m->on_image(view(desired, at(0)), 0).taught);
}

TEST_F(Frames, WithoutCameraInfoTheServoWaits) {
  ServoConfig c;
  auto p = std::make_unique<ServoPipeline>(pattern::WindowTable(cell->projector->pattern(), {3, 3}), c);
  ServoStateMachine m(std::move(p), ServoTiming{});
  EXPECT_EQ(m.on_image(view(desired, at(0)), 0).reason, "waiting for camera_info");
}

// item 8: a false CONVERGED at iteration 1, from frames rendered before the RESET took effect
TEST_F(Frames, ConvergenceCountsOnlyOnFramesWhoseTwistIsApplied) {
  auto m = make();
  m->on_command(static_cast<int>(cell_dds::SimCommand::kTeach));
  m->on_command(static_cast<int>(cell_dds::SimCommand::kReset));
  m->on_command(static_cast<int>(cell_dds::SimCommand::kStart));
  // a frame from before the teach frame is not taught from
  m->on_sim_status({at(0), false, false});
  EXPECT_FALSE(m->on_image(view(initial, at(0)), 0.00).taught);
  EXPECT_EQ(m->state(), ServoState::kTeaching);
  m->on_sim_status({at(1), false, true});
  const ServoReply taught = m->on_image(view(desired, at(1)), 0.04);
  EXPECT_TRUE(taught.taught);
  EXPECT_EQ(m->state(), ServoState::kServoing);
  // still at the desired pose, but the sim has not applied START yet: no convergence
  m->on_sim_status({at(2), false, false});
  const ServoReply early = m->on_image(view(desired, at(2)), 0.08);
  EXPECT_NE(early.state, ServoState::kConverged);
  EXPECT_TRUE(early.twist.isZero());
  EXPECT_EQ(early.iteration, 0u);
  // the first applied frame is at the initial pose: servoing, with a twist
  m->on_sim_status({at(3), true, false});
  const ServoReply step = m->on_image(view(initial, at(3)), 0.12);
  EXPECT_EQ(step.state, ServoState::kServoing);
  EXPECT_FALSE(step.twist.isZero());
  EXPECT_EQ(step.iteration, 1u);
}

// once a simulator sends statuses, a frame whose status never came is not answered (it may be
// the teach frame); in lockstep the simulator sends it again with its status
TEST_F(Frames, FrameWithoutItsSimStatusIsNotAnswered) {
  auto m = make();
  m->on_command(static_cast<int>(cell_dds::SimCommand::kTeach));
  m->on_sim_status({at(0), false, false});
  EXPECT_TRUE(m->on_image(view(desired, at(0)), 0).answer);
  const ServoReply r = m->on_image(view(desired, at(1)), 0.04);
  EXPECT_FALSE(r.answer);
  EXPECT_FALSE(r.taught);
  m->on_sim_status({at(1), false, true});
  EXPECT_TRUE(m->on_image(view(desired, at(1)), 1.04).taught);
}

// item 9: START more than lost_ms after TEACH was undone by the LOST recovery
TEST_F(Frames, LostDoesNotUndoAStartThatCameMeanwhile) {
  auto m = make();
  m->on_command(static_cast<int>(cell_dds::SimCommand::kTeach));
  m->on_sim_status({at(0), false, true});
  EXPECT_TRUE(m->on_image(view(desired, at(0)), 0).taught);
  EXPECT_EQ(m->state(), ServoState::kIdle);
  EXPECT_FALSE(m->tick(2.0));  // idle: no images expected, nothing lost
  m->on_command(static_cast<int>(cell_dds::SimCommand::kStart));
  EXPECT_EQ(m->state(), ServoState::kServoing);
  m->on_sim_status({at(1), true, false});
  m->on_image(view(initial, at(1)), 2.1);
  EXPECT_EQ(m->state(), ServoState::kServoing);
  // images stop while servoing: LOST once, zero twist; then they come back
  const auto lost = m->tick(2.7);
  ASSERT_TRUE(lost);
  EXPECT_EQ(lost->state, ServoState::kLost);
  EXPECT_TRUE(lost->twist.isZero());
  EXPECT_FALSE(m->tick(3.0));
  m->on_sim_status({at(2), true, false});
  m->on_image(view(initial, at(2)), 3.1);
  EXPECT_EQ(m->state(), ServoState::kServoing);
}

// Issue 18, item 11: a RESET or LOAD_SCENARIO the simulator refuses changes nothing. The servo
// idles on the command, but frames rendered running after it prove the refusal, and it goes
// on servoing; a frame that is not running proves the command was obeyed, and START is needed.
TEST_F(Frames, ARefusedResetOrLoadDoesNotStopTheRun) {
  for (const cell_dds::SimCommand jump : {cell_dds::SimCommand::kLoadScenario, cell_dds::SimCommand::kReset}) {
    auto m = make();
    m->on_command(static_cast<int>(cell_dds::SimCommand::kTeach));
    m->on_command(static_cast<int>(cell_dds::SimCommand::kStart));
    m->on_sim_status({at(0), false, true});
    ASSERT_TRUE(m->on_image(view(desired, at(0)), 0).taught);
    m->on_sim_status({at(1), true, false, true});
    EXPECT_FALSE(m->on_image(view(initial, at(1)), 0.04).twist.isZero());
    m->on_command(static_cast<int>(jump));  // refused by the simulator: it runs on
    EXPECT_EQ(m->state(), ServoState::kIdle);
    ServoReply r;
    for (int k = 2; k < 2 + 3; ++k) {
      m->on_sim_status({at(k), true, false, true});
      r = m->on_image(view(initial, at(k)), 0.04 * k);
    }
    EXPECT_EQ(m->state(), ServoState::kServoing) << static_cast<int>(jump);
    EXPECT_FALSE(r.twist.isZero()) << "the run did not go on after a refused command";

    // obeyed: the next frame is not running, and the servo waits for START; when the
    // simulator runs again (a START it heard), the servo follows it
    m->on_command(static_cast<int>(jump));
    m->on_sim_status({at(10), false, false, false});
    r = m->on_image(view(initial, at(10)), 1.0);
    EXPECT_EQ(m->state(), ServoState::kIdle);
    EXPECT_TRUE(r.twist.isZero());
    m->on_sim_status({at(11), true, false, true});
    r = m->on_image(view(initial, at(11)), 1.04);
    EXPECT_EQ(m->state(), ServoState::kServoing);
    EXPECT_FALSE(r.twist.isZero());
  }
}

// issue 43: the simulator is the authority on the run (a servo started after the START, or
// one that missed it on rt/sim/accepted, which keeps nothing for late joiners): a START only it heard
// still starts the run, the servo following its RUNNING frames; a servo that stopped (paused
// or stopped itself) is not started by them.
TEST_F(Frames, AStartOnlyTheSimulatorHeardStartsTheServo) {
  auto m = make();
  m->on_command(static_cast<int>(cell_dds::SimCommand::kTeach));  // no RESET, no START here
  m->on_sim_status({at(0), false, true});
  ASSERT_TRUE(m->on_image(view(desired, at(0)), 0).taught);
  EXPECT_EQ(m->state(), ServoState::kIdle);
  m->on_sim_status({at(1), false, false, false});  // the simulator has not started yet
  EXPECT_TRUE(m->on_image(view(initial, at(1)), 0.04).twist.isZero());
  EXPECT_EQ(m->state(), ServoState::kIdle);
  m->on_sim_status({at(2), true, false, true});  // it runs: its START
  const ServoReply r = m->on_image(view(initial, at(2)), 0.08);
  EXPECT_EQ(r.state, ServoState::kServoing);
  EXPECT_FALSE(r.twist.isZero());
  EXPECT_NE(r.notice.find("did not hear"), std::string::npos) << r.notice;
  m->on_command(static_cast<int>(cell_dds::SimCommand::kPause));  // only the servo heard it
  m->on_sim_status({at(3), true, false, true});
  EXPECT_TRUE(m->on_image(view(initial, at(3)), 0.12).twist.isZero());
  EXPECT_EQ(m->state(), ServoState::kStopped);
}

TEST_F(Frames, PauseStopsAndResetNeedsANewStart) {
  auto m = make(true);
  m->on_command(static_cast<int>(cell_dds::SimCommand::kTeach));
  m->on_sim_status({at(0), false, true});
  m->on_image(view(desired, at(0)), 0);
  EXPECT_EQ(m->state(), ServoState::kServoing);  // autostart
  m->on_command(static_cast<int>(cell_dds::SimCommand::kPause));
  m->on_sim_status({at(1), true, false});
  const ServoReply r = m->on_image(view(initial, at(1)), 0.04);
  EXPECT_TRUE(r.twist.isZero());
  EXPECT_EQ(r.state, ServoState::kStopped);
  m->on_command(static_cast<int>(cell_dds::SimCommand::kStart));
  EXPECT_EQ(m->state(), ServoState::kServoing);
  m->on_command(static_cast<int>(cell_dds::SimCommand::kReset));
  EXPECT_EQ(m->state(), ServoState::kIdle);
  m->on_command(250);  // unknown: nothing changes
  EXPECT_EQ(m->state(), ServoState::kIdle);
}

// issue 13: with a divergence ratio, an error that runs away stops the robot (zero twist,
// STOPPED, a reason that says so) instead of being followed; START servos again
TEST_F(Frames, ARunawayErrorStopsTheServoWhenAsked) {
  const cv::Mat farther = sim::render_image(*cell, sim::resolve_pose(cell->scenario, "-8 -12 -20 -20 15 20"), 3);
  for (const double ratio : {0.0, 1.2}) {
    auto m = make(false, ratio);
    m->on_command(static_cast<int>(cell_dds::SimCommand::kTeach));
    m->on_sim_status({at(1), false, true});
    ASSERT_TRUE(m->on_image(view(desired, at(1)), 0.04).taught);
    m->on_command(static_cast<int>(cell_dds::SimCommand::kStart));
    m->on_sim_status({at(2), true, false});
    const ServoReply first = m->on_image(view(initial, at(2)), 0.08);
    ASSERT_EQ(first.state, ServoState::kServoing) << first.reason;
    m->on_sim_status({at(3), true, false});
    const ServoReply worse = m->on_image(view(farther, at(3)), 0.12);
    ASSERT_GT(worse.error_norm, 1.2 * first.error_norm) << "the second pose is not farther in the task space";
    if (ratio == 0) {
      EXPECT_EQ(worse.state, ServoState::kServoing);
      EXPECT_FALSE(worse.twist.isZero());
      continue;
    }
    EXPECT_EQ(worse.state, ServoState::kStopped);
    EXPECT_TRUE(worse.twist.isZero());
    EXPECT_NE(worse.reason.find("diverging"), std::string::npos) << worse.reason;
    // stopped: later frames are not servoed until START
    m->on_sim_status({at(4), true, false});
    EXPECT_TRUE(m->on_image(view(initial, at(4)), 0.16).twist.isZero());
    m->on_command(static_cast<int>(cell_dds::SimCommand::kStart));
    m->on_sim_status({at(5), true, false});
    EXPECT_FALSE(m->on_image(view(initial, at(5)), 0.20).twist.isZero());
  }
}

// Issue 20: a safe stop (here a black frame: no spots) holds the robot with a zero twist and
// the servo keeps trying; one that lasts 25 frames in a row stops it, as it ends an in-process
// run (control::SafeStopWatch, used by both)
TEST_F(Frames, ASafeStopThatLastsStopsTheServo) {
  const cv::Mat black = cv::Mat::zeros(desired.rows, desired.cols, desired.type());
  auto m = make();
  m->on_command(static_cast<int>(cell_dds::SimCommand::kTeach));
  m->on_sim_status({at(1), false, true});
  ASSERT_TRUE(m->on_image(view(desired, at(1)), 0.04).taught);
  m->on_command(static_cast<int>(cell_dds::SimCommand::kStart));
  int frame = 2;
  const auto next = [&](const cv::Mat& img) {
    m->on_sim_status({at(frame), true, false});
    const ServoReply r = m->on_image(view(img, at(frame)), 0.04 * frame);
    ++frame;
    return r;
  };
  for (int k = 0; k < 24; ++k) {
    const ServoReply r = next(black);
    ASSERT_EQ(r.state, ServoState::kServoing) << "frame " << k << ": " << r.reason;
    EXPECT_TRUE(r.twist.isZero());
    EXPECT_NE(r.reason.find("safe stop"), std::string::npos) << r.reason;
  }
  const ServoReply back = next(initial);  // the spots are back: servoing again, the count restarts
  EXPECT_EQ(back.state, ServoState::kServoing) << back.reason;
  EXPECT_FALSE(back.twist.isZero());
  for (int k = 0; k < 24; ++k) ASSERT_EQ(next(black).state, ServoState::kServoing);
  const ServoReply stopped = next(black);
  EXPECT_EQ(stopped.state, ServoState::kStopped) << stopped.reason;
  EXPECT_NE(stopped.reason.find("safe stop"), std::string::npos) << stopped.reason;
  EXPECT_NE(stopped.reason.find("stopped"), std::string::npos) << stopped.reason;
  EXPECT_TRUE(next(initial).twist.isZero()) << "a stopped servo moved without START";
  m->on_command(static_cast<int>(cell_dds::SimCommand::kStart));
  EXPECT_FALSE(next(initial).twist.isZero());
}

// A spot the decoder found off its epipolar line (a spill, a split spot) or clipped is reported
// but is no feature of the law: neither taught into s* nor matched (vision::DecodedSpot::apart).
TEST_F(Frames, ASpotOffItsLineIsReportedButIsNoFeature) {
  ServoConfig c;
  c.law.z_hat_m = 0.9;
  const auto& k = cell->scenario.camera.intrinsics;
  c.camera.fx = k.fx, c.camera.fy = k.fy, c.camera.cx = k.cx, c.camera.cy = k.cy;
  ServoPipeline p(pattern::WindowTable(cell->projector->pattern(), {3, 3}), c);
  std::vector<ImageSpot> spots = p.locate(desired, std::nullopt);
  ASSERT_GT(spots.size(), 50U);
  for (const ImageSpot& s : spots) EXPECT_FALSE(s.off_line) << "no line to be off without the calibration";
  spots[3].off_line = true;
  EXPECT_EQ(p.features(spots, std::nullopt).size(), spots.size() - 1);
  EXPECT_EQ(p.teach(spots, std::nullopt), static_cast<int>(spots.size()) - 1);
  spots[3].off_line = false;  // on its line now: not in s*, so still no match
  spots[4].off_line = true;
  spots[5].clipped = true;  // a clipped footprint (vision::DecodedSpot::clipped) is no feature either
  const StepResult r = p.step(spots, std::nullopt);
  EXPECT_EQ(r.decoded, static_cast<int>(spots.size()));
  EXPECT_EQ(r.matched.size(), spots.size() - 3);
  for (const auto& m : r.matched)
    for (const int k : {3, 4, 5}) EXPECT_FALSE(m.row == spots[k].row && m.col == spots[k].col) << k;
}

}  // namespace
}  // namespace servo
