#include "sim/session/cell_state_machine.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <tuple>

#include "common/strict_yaml.hpp"
#include "sim/geometry/se3.hpp"

namespace sim {
namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

// Untrusted text made safe for a one-line message.
std::string shown(const std::string& s, std::size_t max = 60) { return common::printable(s, max); }

// The first few rejections of a kind are worth a line each; a flood is summarised.
bool worth_logging(long count) { return count <= 5 || count % 1000 == 0; }

const char* command_name(int c) {
  switch (c) {
    case 0: return "LOAD_SCENARIO";
    case 1: return "RESET";
    case 2: return "TEACH";
    case 3: return "START";
    case 4: return "PAUSE";
    case 5: return "STEP";
    default: return "?";
  }
}

}  // namespace

void write_trace_row(std::ostream& out, const TraceRow& r, bool with_processing) {
  out << r.time_s;
  for (int i = 0; i < 6; ++i) out << ',' << r.twist[i];
  out << ',' << (r.status ? r.status->error_norm : std::nan("")) << ',' << (r.status ? r.status->decoded : 0) << ','
      << (r.status ? r.status->matched : 0) << ',' << r.translation_error_m << ',' << r.rotation_error_deg << ','
      << limit_names(r.robot_limits);
  if (with_processing) {
    out << ',';
    if (r.processing_s) out << 1e3 * *r.processing_s;
  }
  out << '\n';
}

FrameStamp frame_stamp(std::uint64_t index, double dt_s) {
  const std::uint64_t ns = index * static_cast<std::uint64_t>(std::llround(dt_s * 1e9));
  return {static_cast<std::int64_t>(ns / 1000000000ull), static_cast<std::uint32_t>(ns % 1000000000ull)};
}

CellStateMachine::CellStateMachine(const Scenario& scenario, CellOptions params, std::unique_ptr<Robot> robot,
                                   std::optional<GoalPlane> goal)
    : scenario_(scenario), goal_(goal), p_(params), robot_(std::move(robot)),
      scenes_(params.latency.value_or(scenario.latency).acquisition_frames),
      delay_(params.latency.value_or(scenario.latency).processing_frames, params.latency.value_or(scenario.latency).actuation_s) {
  if (!(p_.watchdog_s > 0) || !(p_.physics_period_s > 0) || !(p_.republish_s > 0) || !(p_.teach_timeout_s > 0))
    throw std::invalid_argument("CellStateMachine: watchdog, physics period, republish and teach timeout must be positive");
  if (!robot_)
    robot_ = std::make_unique<FreeFlyingCamera>(scenario_.world_T_desired, scenario_.robot.max_linear_mps,
                                                scenario_.robot.max_angular_radps);
}

void CellStateMachine::loaded(const Scenario& scenario, std::unique_ptr<Robot> robot, std::optional<GoalPlane> goal) {
  scenario_ = scenario;
  goal_ = goal;
  robot_ = robot ? std::move(robot)
                 : std::make_unique<FreeFlyingCamera>(scenario_.world_T_desired, scenario_.robot.max_linear_mps,
                                                      scenario_.robot.max_angular_radps);
  limits_ = 0;
  forget_delays();
  loading_ = false;
  running_ = false;
  steps_ = 0;
  teach_requested_ = false;
  current_.setZero();
  statuses_.clear();
  last_applied_frame_.reset();
  newest_sent_frame_.reset();
  log("cellsim: loaded " + shown(scenario.file.string(), 200));
}

void CellStateMachine::load_failed(const std::string& reason) {
  loading_ = false;
  refused("LOAD_SCENARIO refused: " + reason);
}

bool CellStateMachine::on_command(const CommandMsg& c, double now_s) {
  now_s_ = now_s;
  ++counters_.commands;
  // the teach frame is rendered at the desired pose and (lockstep) answered before anything
  // else happens (the servo takes s* from it); what comes meanwhile waits, in a bounded queue
  if (teach_requested_ || (awaited_ && awaited_->frame.teach) || loading_ || !deferred_.empty()) {
    if (deferred_.size() >= kMaxQueuedCommands) {
      ++counters_.dropped_inputs;
      refused(std::string(command_name(c.command)) + " refused: " + std::to_string(kMaxQueuedCommands) +
          " commands already wait for the teach frame or a load");
      return false;
    }
    deferred_.push_back(c);
    return true;
  }
  const long refused = counters_.commands_refused;
  apply_command(c, now_s);
  return counters_.commands_refused == refused;
}

void CellStateMachine::apply_command(const CommandMsg& c, double now_s) {
  const long refused_before = counters_.commands_refused;
  obey(c, now_s);
  if (counters_.commands_refused == refused_before) out_.accepted.push_back(c);
}

void CellStateMachine::obey(const CommandMsg& c, double /*now_s*/) {
  const auto refuse = [&](const std::string& why) {
    refused(std::string(command_name(c.command)) + " refused: " + why);
  };
  switch (c.command) {
    case static_cast<int>(cell_dds::SimCommand::kLoadScenario): {
      if (c.argument.empty() || c.argument.size() > 4096) return refuse("argument must be a scenario file path");
      for (const char ch : c.argument)
        if (static_cast<unsigned char>(ch) < 0x20) return refuse("path '" + shown(c.argument) + "' has control characters");
      stop_motion();
      loading_ = true;
      out_.load = std::filesystem::path(c.argument);
      return;
    }
    case static_cast<int>(cell_dds::SimCommand::kReset): {
      try {
        place_robot(c.pose ? *c.pose : resolve_pose(scenario_, c.argument.empty() ? "initial" : c.argument));
      } catch (const std::exception& e) {
        return refuse(e.what());
      }
      return;
    }
    case static_cast<int>(cell_dds::SimCommand::kTeach):
      try {
        place_robot(scenario_.world_T_desired);
      } catch (const std::exception& e) {
        return refuse(e.what());
      }
      teach_requested_ = true;
      return;
    case static_cast<int>(cell_dds::SimCommand::kStart): running_ = true; return;
    case static_cast<int>(cell_dds::SimCommand::kPause):
      stop_motion();
      return;
    case static_cast<int>(cell_dds::SimCommand::kStep): {
      const std::uint64_t n = std::clamp<std::uint64_t>(c.steps, 1, kMaxSteps);
      if (c.steps > kMaxSteps)
        log("cellsim: STEP " + std::to_string(c.steps) + " capped at " + std::to_string(kMaxSteps) + " frames");
      steps_ = std::min(kMaxSteps, steps_ + n);
      return;
    }
    default: return refuse("unknown command " + std::to_string(c.command));
  }
}

// Whatever was moving the robot is dropped: the awaited frame, the run, pending steps.
void CellStateMachine::stop_motion() {
  abandon_awaited();
  running_ = false;
  steps_ = 0;
  current_.setZero();
}

// RESET and TEACH: the robot at the pose (it throws, and nothing changes, when it cannot be
// there), stopped.
void CellStateMachine::place_robot(const Eigen::Isometry3d& world_T_camera) {
  robot_->reset(world_T_camera);
  limits_ = 0;
  stop_motion();
  forget_delays();
}

void CellStateMachine::forget_delays() {
  const Latency& latency = p_.latency.value_or(scenario_.latency);
  scenes_ = FrameDelay<std::pair<Eigen::Isometry3d, std::vector<Eigen::Isometry3d>>>(latency.acquisition_frames);
  delay_ = TwistDelay(latency.processing_frames, latency.actuation_s);
}

void CellStateMachine::delay_scene(FrameOrder& f) {
  if (p_.latency.value_or(scenario_.latency).acquisition_frames <= 0 || !f.applies_twist) return;
  std::tie(f.scene_world_T_camera, f.scene_world_T_links) = scenes_.push({f.world_T_camera, f.world_T_links});
}

void CellStateMachine::abandon_awaited() {
  // the frame's index stays used: an answer to it arriving later is stale, never applied to
  // a robot that has been moved or stopped since
  awaited_.reset();
  answer_.reset();
}

std::optional<std::uint64_t> CellStateMachine::frame_of(std::int64_t sec, std::uint32_t nanosec, std::string& why) const {
  if (sec < 0 || nanosec >= 1000000000u || sec > (std::int64_t{1} << 40)) {
    why = "invalid stamp " + std::to_string(sec) + " s " + std::to_string(nanosec) + " ns";
    return std::nullopt;
  }
  const auto ns = static_cast<std::uint64_t>(sec) * 1000000000ull + nanosec;
  // dt >= 1e-4 s is checked at load, so the divisor is at least 100000 ns
  const auto dt_ns = static_cast<std::uint64_t>(std::llround(scenario_.dt_s * 1e9));
  return ns / dt_ns;
}

bool CellStateMachine::on_twist(const TwistMsg& t, double now_s) {
  if (!t.twist.allFinite()) {
    if (worth_logging(++counters_.rejected_nan))
      log("cellsim: rt/servo/cmd_twist: rejected a twist with NaN/Inf (" + std::to_string(counters_.rejected_nan) +
          " so far)");
    return false;
  }
  if (t.frame_id != "camera_optical") {
    if (worth_logging(++counters_.rejected_frame))
      log("cellsim: rt/servo/cmd_twist: rejected a twist in frame '" + shown(t.frame_id) + "' (expected camera_optical)");
    return false;
  }
  std::string why;
  const std::optional<std::uint64_t> k = frame_of(t.stamp_sec, t.stamp_nanosec, why);
  if (k) {
    if (p_.timing == Timing::kLockstep) {
      // an answer to a frame already stepped or given up is the normal echo of a repeated frame
      if (!awaited_ || *k < awaited_->frame.index) {
        ++counters_.late_answers;
        return false;
      }
      if (*k != awaited_->frame.index)
        why = "answers frame " + std::to_string(*k) + ", frame " + std::to_string(awaited_->frame.index) + " is awaited";
    } else {
      const std::uint64_t newest = newest_sent_frame_.value_or(0);
      if (!newest_sent_frame_ || *k > newest) why = "answers frame " + std::to_string(*k) + ", not sent yet";
      else if (last_applied_frame_ && *k < *last_applied_frame_)
        why = "older than the twist in force (frame " + std::to_string(*last_applied_frame_) + ")";
      else if (static_cast<double>(newest - *k) * scenario_.dt_s > p_.watchdog_s + 1e-9)
        why = "stamped " + std::to_string(static_cast<double>(*k) * scenario_.dt_s) + " s, " +
              std::to_string(static_cast<long long>(1e3 * (newest - *k) * scenario_.dt_s)) +
              " ms behind the newest frame (watchdog " + std::to_string(static_cast<long long>(1e3 * p_.watchdog_s)) +
              " ms)";
    }
  }
  if (!why.empty()) {
    if (worth_logging(++counters_.rejected_stale)) log("cellsim: rt/servo/cmd_twist: rejected a twist: " + why);
    return false;
  }
  if (p_.timing == Timing::kLockstep) {
    if (!answer_) {
      answer_ = t.twist;
      awaited_->answered_at_s = now_s;
    }
  } else {
    current_ = t.twist;
    const auto sent = sent_at_s_.find(*k);
    current_processing_s_ = sent == sent_at_s_.end() ? std::nullopt : std::optional<double>(now_s - sent->second);
    last_applied_frame_ = *k;
    valid_until_s_ = now_s + p_.watchdog_s;
    watchdog_tripped_ = false;
  }
  return true;
}

void CellStateMachine::on_servo_status(const ServoReport& report, double now_s) {
  now_s_ = now_s;
  std::string why;
  const std::optional<std::uint64_t> k = frame_of(report.stamp_sec, report.stamp_nanosec, why);
  if (!k) return;
  // a status for a frame not made yet answers nothing: kept, 64 of them would push out every
  // real status as it came and stall each lockstep step for its grace time (issue 40, item 3)
  const std::uint64_t newest = frame_ == 0 ? 0 : frame_ - 1;
  if (*k > newest) {
    if (worth_logging(++counters_.statuses_refused))
      log("cellsim: rt/servo/status: refused a status for frame " + std::to_string(*k) + ", not sent yet (" +
          std::to_string(counters_.statuses_refused) + " so far)");
    return;
  }
  ServoReport s = report;
  if (s.reason.size() > kMaxReasonBytes) s.reason.resize(kMaxReasonBytes);  // what is kept is bounded in bytes
  statuses_[*k] = s;
  peer_sends_statuses_ = true;
  while (statuses_.size() > kMaxKeptStatuses) statuses_.erase(statuses_.begin());
  if (p_.exit_on_converged && s.state == cell_dds::to_wire(cell_dds::ServoState::kConverged)) check_convergence(s);
  // the servo stopped itself while the run was on (a safe stop that lasted, a runaway)
  if (p_.exit_on_stop && s.state == cell_dds::to_wire(cell_dds::ServoState::kStopped) && running_ && !done_)
    end_session(SessionEnd::kServoStopped, shown(s.reason, 200));
}

// One escaping rule and one length for the log and rt/sim/status, and a flood of bad commands
// said at most kRefusalsPerSecond a second (a burst of kRefusalBurst), the rest counted and
// named with the next line said: a 50 s flood of refused loads once wrote 158 MB of log.
void CellStateMachine::refused(std::string line) {
  ++counters_.commands_refused;
  line = shown(line, kMaxRefusalChars);
  refusal_tokens_ = std::min(kRefusalBurst, refusal_tokens_ + std::max(0.0, now_s_ - refusal_tokens_at_s_) * kRefusalsPerSecond);
  refusal_tokens_at_s_ = std::max(refusal_tokens_at_s_, now_s_);
  if (refusal_tokens_ < 1) {
    ++refusals_unsaid_;
    return;
  }
  refusal_tokens_ -= 1;
  if (refusals_unsaid_ > 0) {
    line = "(" + std::to_string(refusals_unsaid_) + " refusals not said) " + line;
    refusals_unsaid_ = 0;
  }
  log("cellsim: " + line);
  out_.refusals.push_back(std::move(line));
}

void CellStateMachine::end_session(SessionEnd kind, std::string reason) {
  done_ = true;
  if (end_.kind != SessionEnd::kNone) return;  // the first stop is the one that ended it
  end_ = {kind, std::move(reason)};
}

void CellStateMachine::check_convergence(const ServoReport& s) {
  // the servo's word is checked against the truth: a CONVERGED for a stale frame, another run
  // or a rogue publisher must not end a session with the robot away from the goal
  const Eigen::Isometry3d wTc = robot_->world_T_camera();
  const GoalError e = goal_error(wTc, scenario_.world_T_desired, goal_);
  const double t = e.translation_m, r = e.rotation_rad * kRadToDeg;
  if (t <= p_.accept_translation_m && r <= p_.accept_rotation_deg) {
    end_session(SessionEnd::kConverged, "converged: " + shown(s.reason, 200));
    return;
  }
  if (converged_refusals_logged_++ < 5) {
    char line[256];
    std::snprintf(line, sizeof line,
                  "cellsim: rt/servo/status: CONVERGED (stamp %lld.%09u) not accepted: the camera is %.1f mm, %.2f deg "
                  "from the desired pose",
                  static_cast<long long>(s.stamp_sec), s.stamp_nanosec, 1e3 * t, r);
    log(line);
  }
}

bool CellStateMachine::move(const Vector6d& twist, double duration_s) {
  return moved(robot_->move(twist, duration_s, scenario_.workspace));
}

bool CellStateMachine::moved(const MotionReport& r) {
  limits_ = r.limits;
  if (!r.event.empty()) {
    if (r.limits & kLimitWorkspace) {
      if (worth_logging(++counters_.rejected_workspace)) log("cellsim: " + r.event);
    } else if (stopped_until_reset(r)) {
      if (worth_logging(++counters_.robot_stops)) log("cellsim: " + r.event);
      // the robot holds still until a reset: a session that ends on stops ends here
      if (p_.exit_on_stop && running_) end_session(SessionEnd::kRobotStopped, "robot stop: " + robot_stop_reason(r.event));
    }
  }
  return r.event.empty();
}

FrameOrder CellStateMachine::order(bool teach, bool repeat) const {
  FrameOrder f;
  f.index = frame_;
  f.time_s = static_cast<double>(frame_) * scenario_.dt_s;
  f.world_T_camera = robot_->world_T_camera();
  f.reported_world_T_camera = robot_->reported_world_T_camera();
  f.scene_world_T_camera = f.world_T_camera;
  f.teach = teach;
  f.applies_twist = !teach && (running_ || steps_ > 0);
  f.repeat = repeat;
  f.world_T_links = robot_->world_T_links();
  f.scene_world_T_links = f.world_T_links;
  f.joint_names = robot_->joint_names();
  f.joint_positions = robot_->joint_positions();
  f.joint_velocities = robot_->joint_velocities();
  f.robot_limits = limits_;
  return f;
}

std::optional<ServoReport> CellStateMachine::status_for(std::uint64_t frame) const {
  const auto it = statuses_.find(frame);
  if (it == statuses_.end()) return std::nullopt;
  return it->second;
}

TraceRow CellStateMachine::row(const FrameOrder& f, const Vector6d& twist, const std::optional<ServoReport>& st) const {
  TraceRow r;
  r.time_s = static_cast<double>(f.index - run_first_frame_) * scenario_.dt_s;
  r.twist = twist;
  r.status = st;
  r.robot_limits = f.robot_limits;
  const Eigen::Isometry3d& wTc = f.world_T_camera;
  const GoalError e = goal_error(wTc, scenario_.world_T_desired, goal_);
  r.translation_error_m = e.translation_m;
  r.rotation_error_deg = e.rotation_rad * kRadToDeg;
  return r;
}

// A lockstep row waits for its frame's status (it travels on another topic and may land
// after the twist), at most two frames.
void CellStateMachine::flush_trace(bool all) {
  while (!trace_pending_.empty()) {
    auto& [frame, r] = trace_pending_.front();
    if (!r.status) r.status = status_for(frame);
    if (!r.status && !all && frame + 2 >= frame_) break;
    out_.trace.push_back(r);
    trace_pending_.pop_front();
  }
}

void CellStateMachine::drain_deferred(double now_s) {
  while (!deferred_.empty() && !teach_requested_ && !(awaited_ && awaited_->frame.teach) && !loading_) {
    const CommandMsg c = deferred_.front();
    deferred_.pop_front();
    apply_command(c, now_s);
  }
}

// The status and the twist travel on two topics and either may land first. A lockstep step
// waits for both, so the trace and the convergence check see the same statuses whatever the
// delivery order or the load: the two-process trace equals the in-process one. A twist-only
// client (it never sent a status) is not kept waiting.
bool CellStateMachine::answer_complete(double now_s) const {
  if (!peer_sends_statuses_ || status_for(awaited_->frame.index)) return true;
  return now_s - awaited_->answered_at_s.value_or(now_s) > kStatusGraceS;
}

void CellStateMachine::lockstep(double now_s) {
  drain_deferred(now_s);
  if (loading_) return;
  if (awaited_ && answer_ && awaited_->frame.teach && answer_complete(now_s)) {
    // a servo that answered the teach frame without taking s* from it (its camera_info not
    // there yet, under load) gets the same frame again, not a new TEACH later: a new teach
    // frame has another index, so other noise, and the run would no longer be the in-process
    // one (issue 18: seen on a loaded machine)
    const std::optional<ServoReport> st = status_for(awaited_->frame.index);
    if (st && st->reason.rfind("taught", 0) != 0 && now_s - awaited_->first_sent_at_s <= p_.teach_timeout_s) {
      answer_.reset();
      awaited_->answered_at_s.reset();
      statuses_.erase(awaited_->frame.index);  // the repeat's answer brings its own
    }
  }
  if (awaited_) {
    if (answer_) {
      if (answer_complete(now_s)) {
        if (awaited_->frame.applies_twist) {
          trace_pending_.emplace_back(awaited_->frame.index, row(awaited_->frame, *answer_, std::nullopt));
          // the run's own clock, as the in-process runner's, so both integrate the same pieces
          const double t = static_cast<double>(awaited_->frame.index - run_first_frame_) * scenario_.dt_s;
          moved(delay_.step(*robot_, *answer_, t, scenario_.dt_s, scenario_.workspace));
          trace_pending_.back().second.robot_limits = limits_;
          ++counters_.applied;
        }
        abandon_awaited();
        drain_deferred(now_s);  // the commands that waited for the teach frame
      }
    } else if (awaited_->frame.teach && now_s - awaited_->first_sent_at_s > p_.teach_timeout_s) {
      log("cellsim: no answer to the teach frame within " + std::to_string(static_cast<int>(p_.teach_timeout_s)) +
          " s (is a servo running?): going on");
      abandon_awaited();
      drain_deferred(now_s);
    } else if (done_ && now_s - awaited_->first_sent_at_s > 0.5) {
      abandon_awaited();
    } else if (now_s - awaited_->sent_at_s > p_.republish_s) {
      // the same frame again: a restarted servo picks the run up
      out_.frames.push_back(awaited_->frame);
      out_.frames.back().repeat = true;
      awaited_->sent_at_s = now_s;
    }
  }
  if (!awaited_ && !done_ && (teach_requested_ || running_ || steps_ > 0)) {
    if (p_.max_frames > 0 && counters_.frames >= p_.max_frames) {
      end_session(SessionEnd::kFrameCap, "frame cap (" + std::to_string(p_.max_frames) + ") reached");
    } else if (p_.max_run_steps > 0 && counters_.applied >= p_.max_run_steps && !teach_requested_) {
      end_session(SessionEnd::kStepCap, "iteration cap (" + std::to_string(p_.max_run_steps) + ") reached");
    } else {
      const bool teach = teach_requested_;
      teach_requested_ = false;
      FrameOrder f = order(teach, false);
      if (teach) forget_delays();
      delay_scene(f);
      if (!teach && !running_ && steps_ > 0) --steps_;
      if (running_ && !run_started_at_) {
        run_started_at_ = now_s;
        run_first_frame_ = f.index;
      }
      ++frame_;
      ++counters_.frames;
      out_.frames.push_back(f);
      awaited_ = Awaited{f, now_s, now_s, std::nullopt};
    }
  }
  flush_trace(false);
}

void CellStateMachine::realtime(double now_s) {
  if (physics_at_s_ < 0) {
    physics_at_s_ = now_s;
    next_frame_at_s_ = now_s;
  }
  if (loading_) {
    physics_at_s_ = now_s;
    return;
  }
  drain_deferred(now_s);  // what waited for a load or for the teach frame to go out
  // motion: the twist in force acts until the watchdog's instant, integrated in physics steps
  const bool moving = running_ || steps_ > 0;
  while (physics_at_s_ < now_s) {
    const double t1 = std::min(now_s, physics_at_s_ + p_.physics_period_s);
    if (moving && !current_.isZero(0)) {
      const double end = std::min(t1, valid_until_s_);
      if (end > physics_at_s_ && !move(current_, end - physics_at_s_)) current_.setZero();
      if (valid_until_s_ <= t1 && !current_.isZero(0)) {
        ++counters_.watchdog_stops;
        log("cellsim: watchdog: no valid twist for " + std::to_string(static_cast<long long>(1e3 * p_.watchdog_s)) +
            " ms, robot stopped");
        current_.setZero();
        watchdog_tripped_ = true;
      }
    }
    physics_at_s_ = t1;
  }
  // frames at the camera's period; a service that fell far behind skips ahead
  if (now_s - next_frame_at_s_ > 5 * scenario_.dt_s) next_frame_at_s_ = now_s;
  while (now_s >= next_frame_at_s_ && !done_) {
    if (p_.max_frames > 0 && counters_.frames >= p_.max_frames) {
      end_session(SessionEnd::kFrameCap, "frame cap (" + std::to_string(p_.max_frames) + ") reached");
      break;
    }
    if (p_.max_run_steps > 0 && counters_.applied >= p_.max_run_steps) {
      end_session(SessionEnd::kStepCap, "iteration cap (" + std::to_string(p_.max_run_steps) + ") reached");
      break;
    }
    const bool teach = teach_requested_;
    teach_requested_ = false;
    const FrameOrder f = order(teach, false);
    if (f.applies_twist) {
      if (!run_started_at_) {
        run_started_at_ = now_s;
        run_first_frame_ = f.index;
      }
      ++counters_.applied;
      out_.trace.push_back(row(f, current_, statuses_.empty() ? std::nullopt
                                                                    : std::optional<ServoReport>(statuses_.rbegin()->second)));
      if (!current_.isZero(0)) out_.trace.back().processing_s = current_processing_s_;
      if (!running_ && steps_ > 0) --steps_;
    }
    newest_sent_frame_ = f.index;
    sent_at_s_[f.index] = now_s;
    while (sent_at_s_.size() > kMaxKeptStatuses) sent_at_s_.erase(sent_at_s_.begin());
    ++frame_;
    ++counters_.frames;
    out_.frames.push_back(f);
    next_frame_at_s_ += scenario_.dt_s;
  }
}

CellOutput CellStateMachine::poll(double now_s) {
  now_s_ = now_s;
  if (last_poll_s_ && moving_at_last_poll_ && now_s > *last_poll_s_) counters_.stepping_s += now_s - *last_poll_s_;
  if (p_.timing == Timing::kLockstep) lockstep(now_s);
  else realtime(now_s);
  last_poll_s_ = now_s;
  moving_at_last_poll_ = !loading_ && (running_ || steps_ > 0 || (awaited_ && awaited_->frame.applies_twist));
  if (done_ && !awaited_) {
    flush_trace(true);
    out_.done = true;
  }
  CellOutput out = std::move(out_);
  out_ = CellOutput{};
  return out;
}

double CellStateMachine::next_deadline(double now_s) const {
  if (p_.timing == Timing::kLockstep) {
    if (awaited_ && answer_ && awaited_->answered_at_s) return *awaited_->answered_at_s + kStatusGraceS + 1e-6;
    if (awaited_) {
      const double republish = awaited_->sent_at_s + p_.republish_s;
      return awaited_->frame.teach ? std::min(republish, awaited_->first_sent_at_s + p_.teach_timeout_s) : republish;
    }
    return now_s + 0.05;
  }
  const bool moving = (running_ || steps_ > 0) && !current_.isZero(0);
  const double frame = next_frame_at_s_ < 0 ? now_s : next_frame_at_s_;
  return moving ? std::min(frame, now_s + p_.physics_period_s) : frame;
}

}  // namespace sim

namespace sim {

AutorunSequence::Step AutorunSequence::poll(double now_s, bool servo_seen, bool taught) {
  Step step;
  if (!started_s_) started_s_ = now_s;
  const auto teach = [&] {
    step.send.push_back({static_cast<int>(cell_dds::SimCommand::kTeach), "", 0});
    teach_sent_s_ = now_s;
    ++sent_;
  };
  switch (stage_) {
    case Stage::kWaitServo:
      if (servo_seen || now_s - *started_s_ > wait_s_) {
        if (!servo_seen)
          step.log.push_back("cellsim: autorun: no servo status after " + std::to_string(static_cast<int>(wait_s_)) +
                             " s, sending TEACH anyway");
        teach();
        stage_ = Stage::kTeach;
      }
      break;
    case Stage::kTeach:
      if (taught) {
        step.send.push_back({static_cast<int>(cell_dds::SimCommand::kReset), "initial", 0});
        step.send.push_back({static_cast<int>(cell_dds::SimCommand::kStart), "", 0});
        stage_ = Stage::kDone;
      } else if (now_s - *teach_sent_s_ > retry_s_) {
        if (sent_ >= attempts_) {
          step.log.push_back("cellsim: autorun: the servo did not report being taught after " + std::to_string(sent_) +
                             " TEACH commands; giving up (send TEACH, RESET and START by hand)");
          stage_ = Stage::kDone;
        } else {
          step.log.push_back("cellsim: autorun: no \"taught\" status yet, sending TEACH again");
          teach();
        }
      }
      break;
    case Stage::kDone: break;
  }
  step.finished = stage_ == Stage::kDone;
  return step;
}

}  // namespace sim
