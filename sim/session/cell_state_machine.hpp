// The simulated cell's logic, as `cellsim serve` runs it: commands (teach, start, pause,
// step, reset, load), lockstep and realtime stepping, the watchdog, and the checks every
// twist passes before it moves the robot. A pure state machine over plain messages and a
// time argument: it never waits, never touches DDS, files or clocks. The service feeds it
// what arrives, calls poll(now) and carries out what the returned CellOutput says (render
// and publish frames, write trace rows, load a scenario, print lines).
//
// Safety rules it enforces (docs/topics.md, Safety):
// - a twist moves the robot only when finite, in the camera frame, and answering the frame
//   it must answer: lockstep, exactly the frame awaited; realtime, a frame already sent, not
//   older than the last one applied nor than the watchdog period;
// - realtime: no valid twist for watchdog_s and the robot stops, integrated exactly up to
//   that instant (physics substeps between frames, not frame ticks);
// - a motion that would take the camera out of the scenario's workspace is not made;
// - every queue and count it keeps is bounded.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "protocol/servo_state.hpp"
#include "protocol/sim_command.hpp"
#include "sim/session/trace.hpp"
#include "sim/robot/robot.hpp"
#include "sim/robot/twist_delay.hpp"
#include "sim/scenario/scenario.hpp"

namespace sim {

enum class Timing { kLockstep, kRealtime };

struct CommandMsg {
  int command = 0;       // a cell_dds::SimCommand value; anything else is refused
  std::string argument;  // LOAD_SCENARIO: path; RESET: desired | initial | "x y z rx ry rz"
  std::uint64_t steps = 0;
  // RESET to exactly this pose (the in-memory wiring; a DDS command carries text)
  std::optional<Eigen::Isometry3d> pose = std::nullopt;
};

struct TwistMsg {
  std::int64_t stamp_sec = 0;     // header stamp, as sent (untrusted)
  std::uint32_t stamp_nanosec = 0;
  std::string frame_id;
  Vector6d twist = Vector6d::Zero();  // (v, w) in the camera frame
};

// What the servo said about one frame (rt/servo/status), for the trace and convergence.
struct ServoReport {
  std::int64_t stamp_sec = 0;
  std::uint32_t stamp_nanosec = 0;
  std::uint8_t state = 0;  // as on the wire (cell_dds::ServoState's values, or any other a client sent)
  double error_norm = 0;
  std::uint32_t decoded = 0, matched = 0;
  std::string reason;
};

// Why a session ended: the one place every stop is decided, for both wirings (the services
// over DDS, the in-memory loop of experiments and campaigns).
enum class SessionEnd {
  kNone,
  kConverged,     // the servo said CONVERGED, and the camera is at the goal (within the acceptance)
  kServoStopped,  // the servo stopped itself: a safe stop that lasted, or a loop running away
  kRobotStopped,  // the robot stopped by itself: a collision, a fault
  kStepCap,       // max_run_steps applied
  kFrameCap,      // max_frames made
};
struct SessionEndReport {
  SessionEnd kind = SessionEnd::kNone;
  std::string reason;  // "converged: ...", "safe stop: ...", "robot stop: collision: link 'A' touches ..."
};

struct CellOptions {
  Timing timing = Timing::kLockstep;
  double watchdog_s = 0.1;        // realtime: no valid twist for this long, the robot stops
  double physics_period_s = 0.001;  // realtime: motion and watchdog are integrated at this step
  double republish_s = 1.0;       // lockstep: frame k sent again when unanswered this long
  double teach_timeout_s = 10.0;  // lockstep: the teach frame is given up after this long
  long max_frames = 0;            // done after this many new frames (0: no limit)
  bool exit_on_converged = false;
  // also end on the servo stopping itself (STOPPED after START) and on the robot stopping
  bool exit_on_stop = false;
  long max_run_steps = 0;         // done after this many applied steps (0: no limit)
  // a CONVERGED status ends the run only when the camera really is this close to the goal
  double accept_translation_m = 0.01;
  double accept_rotation_deg = 1.0;
  // the run's delays (acquisition, processing, actuation), when the run chose other than the
  // scenario's (an experiment's --latency)
  std::optional<Latency> latency;
};

// One frame to render and publish (image, camera pose, sim status, truth, clock).
struct FrameOrder {
  std::uint64_t index = 0;
  double time_s = 0;              // simulated time, index * dt
  Eigen::Isometry3d world_T_camera = Eigen::Isometry3d::Identity();
  // what the robot reports (rt/camera_pose): the true pose unless the scenario has errors
  Eigen::Isometry3d reported_world_T_camera = Eigen::Isometry3d::Identity();
  // what the image shows: the scene now, or, in lockstep with `latency.acquisition_frames`,
  // that of a frames ago (the camera's pose and the arm's links then)
  Eigen::Isometry3d scene_world_T_camera = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Isometry3d> scene_world_T_links;
  bool applies_twist = false;     // a twist answering it will move the robot
  bool teach = false;             // rendered at the desired pose for TEACH
  bool repeat = false;            // lockstep: the same frame again (unanswered)
  // the robot's state when rendered: link poses (ArmRobot::world_T_links; empty for the
  // free-flying camera), joints, and why its last motion was limited
  std::vector<Eigen::Isometry3d> world_T_links;
  std::vector<std::string> joint_names;
  Eigen::VectorXd joint_positions, joint_velocities;
  std::uint32_t robot_limits = 0;
};

// One applied step of the robot.
struct TraceRow {
  double time_s = 0;              // simulated time since the run started
  Vector6d twist = Vector6d::Zero();  // as commanded
  // pose error when the frame was rendered (before the twist moved the robot)
  std::optional<ServoReport> status;
  double translation_error_m = 0, rotation_error_deg = 0;
  std::uint32_t robot_limits = 0;  // why the robot limited this step's motion (RobotLimit bits)
  // realtime: how long the twist in force took, from its frame's publication to its arrival
  // here (decoding, the control law and both DDS hops); none in lockstep, where time waits
  std::optional<double> processing_s;
};

// One trace.csv row (sim::kTraceHeader's columns, then processing_ms when `with_processing`):
// written by the service and the in-memory loop alike, so their traces are the same bytes.
void write_trace_row(std::ostream& out, const TraceRow& r, bool with_processing);

// The header stamp of frame `index`: integer nanoseconds per frame, so stamps map back to
// frames exactly (cell_dds::stamp_of writes the same on the wire).
struct FrameStamp {
  std::int64_t sec = 0;
  std::uint32_t nanosec = 0;
};
FrameStamp frame_stamp(std::uint64_t index, double dt_s);

struct CellCounters {
  long frames = 0, applied = 0, rejected_nan = 0, rejected_frame = 0, rejected_stale = 0, rejected_workspace = 0,
       watchdog_stops = 0, robot_stops = 0, commands = 0, commands_refused = 0, dropped_inputs = 0;
  // lockstep: answers that came after their frame was stepped (a repeated frame answered twice,
  // a frame given up): normal traffic, counted and not logged (issue 18, item 6)
  long late_answers = 0;
  // statuses for frames not sent yet: refused (issue 40, item 3)
  long statuses_refused = 0;
  // wall time during which the robot was asked to move (running, stepping, or a frame awaited
  // whose twist applies): the loop rate is measured over it, not over idle time
  double stepping_s = 0;
};

struct CellOutput {
  std::vector<FrameOrder> frames;
  std::vector<TraceRow> trace;
  std::vector<std::string> log;  // one line each, for stderr
  // the commands refused, one line each ("RESET refused: ..."): also in `log`, and said on
  // rt/sim/status (NOTICE) so that a client learns it from the data, not from our stderr
  std::vector<std::string> refusals;
  // the commands obeyed since the last output, in the order they took effect: the service says
  // them on rt/sim/accepted, where the servo learns them (the simulator is the one reader of
  // rt/sim/control, so a command published once reaches the run)
  std::vector<CommandMsg> accepted;
  std::optional<std::filesystem::path> load;  // load this scenario, then loaded() or load_failed()
  bool done = false;              // max_frames reached or an accepted convergence
};

class CellStateMachine {
 public:
  // `robot`: what carries the camera (make_robot of the cell); null: a free-flying camera
  // `goal`: the plane the task servoes to, when the projector rides on the camera (Cell::goal_plane):
  // the camera is then judged on what the task sees (sim::goal_error), not on its whole pose.
  CellStateMachine(const Scenario& scenario, CellOptions params, std::unique_ptr<Robot> robot = nullptr,
                   std::optional<GoalPlane> goal = std::nullopt);

  // Inputs, as they arrive. Each returns false when the input was refused (and says why in
  // the next output's log).
  bool on_command(const CommandMsg& c, double now_s);
  bool on_twist(const TwistMsg& t, double now_s);
  void on_servo_status(const ServoReport& s, double now_s);

  // Advances to `now_s`: steps, frames, watchdog. Returns what the service must do.
  CellOutput poll(double now_s);
  // Latest time the service may sleep to before calling poll again.
  double next_deadline(double now_s) const;

  // After a CellOutput::load: the scenario was loaded (robot at its desired pose, idle) or not.
  void loaded(const Scenario& scenario, std::unique_ptr<Robot> robot = nullptr, std::optional<GoalPlane> goal = std::nullopt);
  void load_failed(const std::string& reason);

  Eigen::Isometry3d world_T_camera() const { return robot_->world_T_camera(); }
  const Scenario& scenario() const { return scenario_; }
  const std::optional<GoalPlane>& goal_plane() const { return goal_; }
  const CellCounters& counters() const { return counters_; }
  const SessionEndReport& session_end() const { return end_; }
  bool running() const { return running_; }
  std::uint64_t next_frame() const { return frame_; }
  std::uint64_t pending_steps() const { return steps_; }
  double dt() const { return scenario_.dt_s; }
  // wall time of the first step of the run, and steps since (for the loop rate)
  std::optional<double> run_started_at() const { return run_started_at_; }

  // Limits on what is kept between polls.
  static constexpr std::size_t kMaxQueuedCommands = 16;
  static constexpr std::size_t kMaxKeptStatuses = 64;
  // refusals said (logged and on rt/sim/status): a token bucket over the inputs' time
  static constexpr double kRefusalsPerSecond = 10, kRefusalBurst = 20;
  static constexpr std::size_t kMaxRefusalChars = 300;  // rt/sim/status's bound for a refusal
  static constexpr std::size_t kMaxReasonBytes = 256;   // of a kept status's reason
  static constexpr double kStatusGraceS = 0.5;  // lockstep: how long an answer waits for its status
  static constexpr std::uint64_t kMaxSteps = 1'000'000;

 private:
  // a command applied (deferred ones once their turn comes): obeyed, or refused with its
  // reason; an obeyed one is said in CellOutput::accepted
  void apply_command(const CommandMsg& c, double now_s);
  void obey(const CommandMsg& c, double now_s);
  std::optional<std::uint64_t> frame_of(std::int64_t sec, std::uint32_t nanosec, std::string& why) const;
  bool move(const Vector6d& twist, double duration_s);
  // the robot's report of a motion: limits kept, events logged; false when it stopped
  bool moved(const MotionReport& r);
  // forgets the delayed scenes and twists (a reset, a load, a teach)
  void forget_delays();
  // lockstep with an acquisition delay: the frame shows the scene of a frames ago
  void delay_scene(FrameOrder& f);
  void abandon_awaited();
  void stop_motion();
  void place_robot(const Eigen::Isometry3d& world_T_camera);
  FrameOrder order(bool teach, bool repeat) const;
  TraceRow row(const FrameOrder& frame, const Vector6d& twist, const std::optional<ServoReport>& st) const;
  std::optional<ServoReport> status_for(std::uint64_t frame) const;
  void flush_trace(bool all);
  void check_convergence(const ServoReport& s);
  void drain_deferred(double now_s);
  bool answer_complete(double now_s) const;
  void lockstep(double now_s);
  void realtime(double now_s);
  void log(std::string line) { out_.log.push_back(std::move(line)); }
  void end_session(SessionEnd kind, std::string reason);
  void refused(std::string line);
  double now_s_ = 0;  // the latest input's time
  double refusal_tokens_ = kRefusalBurst, refusal_tokens_at_s_ = 0;
  long refusals_unsaid_ = 0;

  Scenario scenario_;
  std::optional<GoalPlane> goal_;
  CellOptions p_;
  std::unique_ptr<Robot> robot_;
  std::uint32_t limits_ = 0;  // why the last motion was limited (RobotLimit bits)
  CellOutput out_;
  CellCounters counters_;
  std::uint64_t frame_ = 0;          // index of the next new frame
  std::uint64_t run_first_frame_ = 0;
  std::uint64_t steps_ = 0;          // STEP frames still to make
  bool running_ = false;
  std::optional<double> last_poll_s_;
  bool moving_at_last_poll_ = false;
  bool teach_requested_ = false;
  bool loading_ = false;
  bool done_ = false;
  SessionEndReport end_;
  std::optional<double> run_started_at_;

  // lockstep: the frame sent and not yet answered
  struct Awaited {
    FrameOrder frame;
    double sent_at_s = 0, first_sent_at_s = 0;
    std::optional<double> answered_at_s;  // when its valid twist arrived
  };
  std::optional<Awaited> awaited_;
  std::optional<Vector6d> answer_;            // the valid twist for the awaited frame
  std::deque<CommandMsg> deferred_;           // lockstep: commands behind the teach frame

  // realtime: the twist in force and until when the watchdog lets it act
  Vector6d current_ = Vector6d::Zero();
  double valid_until_s_ = 0;
  double physics_at_s_ = -1;
  double next_frame_at_s_ = -1;
  std::optional<std::uint64_t> last_applied_frame_;
  std::optional<std::uint64_t> newest_sent_frame_;
  bool watchdog_tripped_ = false;

  std::map<std::uint64_t, ServoReport> statuses_;  // by frame, newest kept
  bool peer_sends_statuses_ = false;               // lockstep: an answer waits for its status
  // lockstep with the scenario's latency: the scenes not delivered yet, the twists on their way
  FrameDelay<std::pair<Eigen::Isometry3d, std::vector<Eigen::Isometry3d>>> scenes_;
  TwistDelay delay_;
  // realtime: when each recent frame went out, and the processing time of the twist in force
  std::map<std::uint64_t, double> sent_at_s_;
  std::optional<double> current_processing_s_;
  std::deque<std::pair<std::uint64_t, TraceRow>> trace_pending_;  // waiting for their status
  int converged_refusals_logged_ = 0;
};

}  // namespace sim

namespace sim {

// `cellsim serve --autorun`: the commands an operator would send (TEACH, then RESET initial
// and START), sent once the servo is there and resent until it says it was taught.
class AutorunSequence {
 public:
  struct Step {
    std::vector<CommandMsg> send;
    std::vector<std::string> log;
    bool finished = false;
  };
  // the retry waits longer than the teach timeout (10 s): a TEACH sent while the first teach
  // frame is still awaited would teach again from another frame
  explicit AutorunSequence(double wait_for_servo_s = 60, double teach_retry_s = 15, int teach_attempts = 5)
      : wait_s_(wait_for_servo_s), retry_s_(teach_retry_s), attempts_(teach_attempts) {}
  // servo_seen: a status from the servo itself has arrived (not merely a matched reader);
  // taught: a status saying "taught" has arrived since the last TEACH was sent.
  Step poll(double now_s, bool servo_seen, bool taught);
  bool finished() const { return stage_ == Stage::kDone; }

 private:
  enum class Stage { kWaitServo, kTeach, kDone };
  double wait_s_, retry_s_;
  int attempts_;
  Stage stage_ = Stage::kWaitServo;
  std::optional<double> started_s_, teach_sent_s_;
  int sent_ = 0;
};

}  // namespace sim
