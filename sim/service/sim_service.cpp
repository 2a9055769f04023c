#include "sim/cell/build_cell.hpp"
#include "sim/service/sim_service.hpp"
#include "sim/session/white_frame_pose.hpp"

#include "common/exit_codes.hpp"
#include "common/output_file.hpp"
#include "common/strict_yaml.hpp"


#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <deque>
#include <future>
#include <iomanip>
#include <mutex>
#include <optional>

#include "cell_msgsPubSubTypes.h"
#include "dds/endpoint.hpp"
#include "dds/ros_graph.hpp"
#include "dds/cli_flags.hpp"
#include "dds/topics.hpp"
#include "foxglove/annotations.hpp"
#include "foxglove/bridge.hpp"
#include "foxglove_msgsPubSubTypes.h"
#include "record/recorder.hpp"
#include "geometry_msgsPubSubTypes.h"
#include "rosgraph_msgsPubSubTypes.h"
#include "sensor_msgsPubSubTypes.h"
#include "std_msgsPubSubTypes.h"
#include "tf2_msgsPubSubTypes.h"
#include "sim/geometry/se3.hpp"
#include "sim/render/renderer.hpp"
#include "sim/arm/robot_model.hpp"
#include "sim/messages/cell_messages.hpp"
#include "sim/session/cell_state_machine.hpp"

namespace sim {
namespace {

using Clock = std::chrono::steady_clock;
using geometry_msgs::msg::dds_::TwistStamped_;
using cell_msgs::msg::dds_::ServoStatus_;
using cell_msgs::msg::dds_::SimControl_;

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

// Everything the DDS listener threads hand to the service loop. Every queue is bounded: a
// flood of twists at an idle sim used to grow without limit (issue 9, item 7).
struct Inbox {
  static constexpr std::size_t kMaxTwists = 16, kMaxCommands = 64, kMaxStatuses = 64;
  std::mutex m;
  std::condition_variable cv;
  std::deque<TwistStamped_> twists;
  std::deque<SimControl_> commands;
  std::deque<ServoStatus_> statuses;
  long dropped = 0;
  // statuses are taken only for frames already sent, and no older than the state machine
  // keeps: a peer's flood of future or ancient stamps cannot push the real one out of the
  // queue (issue 40, item 3). The service loop moves the window as it sends frames.
  std::uint64_t newest_sent_ns = 0, kept_window_ns = 0;
  long statuses_refused = 0;
  bool servo_seen = false;
  bool taught_seen = false;
  template <typename T>
  void push(std::deque<T>& q, T&& v, std::size_t max) {
    std::lock_guard<std::mutex> l(m);
    if (q.size() >= max) {
      q.pop_front();  // the newest matters: a stale twist or status is worth nothing
      ++dropped;
    }
    q.push_back(std::move(v));
    cv.notify_all();
  }
};

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

sim::CommandMsg to_command(const SimControl_& c) { return {c.command(), c.argument(), c.steps(), std::nullopt}; }

sim::TwistMsg to_twist(const TwistStamped_& t) {
  sim::TwistMsg m;
  m.stamp_sec = t.header().stamp().sec();
  m.stamp_nanosec = t.header().stamp().nanosec();
  m.frame_id = t.header().frame_id();
  const auto& l = t.twist().linear();
  const auto& a = t.twist().angular();
  m.twist << l.x(), l.y(), l.z(), a.x(), a.y(), a.z();
  return m;
}

sim::ServoReport to_report(const ServoStatus_& s) {
  return {s.header().stamp().sec(), s.header().stamp().nanosec(), s.state(), s.error_norm(), s.decoded(), s.matched(),
          s.reason()};
}

// What a scenario's errors: and latency: sections do in this service, said once at load.
void announce_conditions(const sim::Scenario& s, TimingMode mode) {
  if (s.errors.any())
    std::printf("cellsim: %s: the servo is told a calibration off by %s (camera_info, rt/camera_pose, the robot's "
                "controller; `cellsim calibration` writes the projector's)\n",
                s.file.filename().c_str(), sim::describe(s.errors, {}).c_str());
  if (s.latency.any() && mode == TimingMode::kLockstep)
    std::printf("cellsim: %s: latency: %s (frames shown late, twists applied late, as in-process)\n",
                s.file.filename().c_str(), sim::describe({}, s.latency).c_str());
  if (s.latency.any() && mode == TimingMode::kRealtime)
    std::printf("cellsim: %s: latency: %s is not added in realtime, where the loop's delays are the real ones "
                "(the trace's processing_ms measures them); lockstep and in-process runs apply it\n",
                s.file.filename().c_str(), sim::describe({}, s.latency).c_str());
}

// Where LOAD_SCENARIO may read from, and what it may say (issue 18, item 10): a remote peer
// names the file, so the path is resolved (links followed) and must lie under the allowed
// folder, and an error never quotes the file's content (an /etc/shadow line once reached the log).
std::filesystem::path allowed_scenario(const std::filesystem::path& requested, const std::filesystem::path& allowed) {
  const std::filesystem::path p = requested.is_relative() ? allowed / requested : requested;
  std::error_code ec;
  const std::filesystem::path real = std::filesystem::canonical(p, ec);
  if (ec) throw std::runtime_error(requested.string() + ": scenario not found under " + allowed.string());
  // component by component: "/a/bc" is not under "/a/b", and everything is under "/"
  const auto [in_allowed, in_real] = std::mismatch(allowed.begin(), allowed.end(), real.begin(), real.end());
  if (in_allowed != allowed.end() || in_real == real.end())
    throw std::runtime_error(requested.string() + ": outside the folder LOAD_SCENARIO may read (" + allowed.string() +
                             "; cellsim serve --scenarios DIR names another)");
  return real;
}

// Everything between quotes goes: values quoted from the file are its content.
std::string without_quoted_content(const std::string& message) {
  std::string out;
  bool in_quote = false;
  for (char ch : message) {
    if (ch == '\'') {
      out += in_quote ? "...'" : "'";
      in_quote = !in_quote;
    } else if (!in_quote) {
      out += ch;
    }
  }
  if (in_quote) out += "...'";
  return out;
}

// A scenario read and built off the service loop: a slow or large one (6-8 s) must not stop
// the status, the watchdog or the other commands.
struct LoadResult {
  std::unique_ptr<sim::Cell> cell;
  std::unique_ptr<sim::Robot> robot;
  std::string error;
};

class SimService {
 public:
  explicit SimService(const ServiceOptions& o) : o_(o) {
    cell_ = sim::build_cell(sim::load_scenario(o.scenario));
    announce_conditions(cell_->scenario, o.mode);
    machine_ = std::make_unique<sim::CellStateMachine>(cell_->scenario, cell_params(o), sim::make_robot(*cell_),
                                                       cell_->goal_plane);
    allowed_dir_ = allowed_scenarios_dir(o);
    open_recording(o);
    try {
      make_endpoints(o);
      if (o.foxglove_port >= 0) {
        foxglove::ServerOptions live;
        live.port = o.foxglove_port;
        live.address = o.foxglove_address;
        live_ = std::make_unique<foxglove::Bridge>(*participant_, o.ns, live);
        std::printf("cellsim: the run live in Foxglove: %s (foxglove.websocket.v1)\n", live_->url().c_str());
        std::fflush(stdout);
      }
      publish_camera_info();
      publish_description();
      open_trace(o);
    } catch (...) {
      // start-up failed: the recording's partial file goes, and no file was touched
      if (recorder_) recorder_->abandon();
      throw;
    }
  }

  int run() {
    std::printf("cellsim: ready (scenario %s, %s, domain %d)\n", cell_->scenario.name.c_str(),
                o_.mode == TimingMode::kLockstep ? "lockstep" : "realtime", o_.domain_id);
    std::fflush(stdout);
    const Clock::time_point t0 = Clock::now();
    sim::AutorunSequence autorun;
    bool autorun_done = !o_.autorun;
    while (!g_stop) {
      const double now = seconds_since(t0);
      // autorun: its commands go out on rt/sim/control and come back through our own reader
      // like any client's (the servo learns them on rt/sim/accepted)
      if (!autorun_done) {
        bool seen, taught;
        {
          std::lock_guard<std::mutex> l(inbox_.m);
          seen = inbox_.servo_seen;
          taught = inbox_.taught_seen;
        }
        const sim::AutorunSequence::Step step = autorun.poll(now, seen && twist_in_->matched() > 0, taught);
        for (const auto& line : step.log) std::fprintf(stderr, "%s\n", line.c_str());
        for (const auto& c : step.send) {
          if (c.command == static_cast<int>(cell_dds::SimCommand::kTeach)) {
            std::lock_guard<std::mutex> l(inbox_.m);
            inbox_.taught_seen = false;
          }
          SimControl_ m = wire::control(c);
          control_out_->write(m);
        }
        autorun_done = step.finished;
      }
      // inputs to the state machine, in arrival order per topic
      std::deque<TwistStamped_> twists;
      std::deque<SimControl_> commands;
      std::deque<ServoStatus_> statuses;
      {
        std::lock_guard<std::mutex> l(inbox_.m);
        twists.swap(inbox_.twists);
        commands.swap(inbox_.commands);
        statuses.swap(inbox_.statuses);
      }
      for (const auto& s : statuses) machine_->on_servo_status(to_report(s), now);
      for (const auto& c : commands) machine_->on_command(to_command(c), now);
      for (const auto& t : twists) machine_->on_twist(to_twist(t), now);
      finish_load();
      sim::CellOutput out = machine_->poll(now);
      if (carry_out(out)) break;
      if (loading_.valid() && now - last_loading_status_s_ >= 0.1) {
        publish_loading_status();
        last_loading_status_s_ = now;
      }
      std::unique_lock<std::mutex> lock(inbox_.m);
      const double deadline = std::max(now + 1e-4, std::min(machine_->next_deadline(now), now + 0.05));
      inbox_.cv.wait_until(lock, t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(deadline)),
                           [this] {
                             return g_stop.load() || !inbox_.twists.empty() || !inbox_.commands.empty() ||
                                    !inbox_.statuses.empty();
                           });
    }
    if (loading_.valid()) loading_.wait();  // a load is bounded by its files' limits; its objects must not outlive us
    // the session's end said on rt/sim/status, and the last pose and status must reach the
    // readers that are matched, not die with the process
    {
      auto ended = status_between_frames(cell_msgs::msg::dds_::SimStatus_Constants::ENDED);
      ended.session_end(session_end_reason());
      sim_status_->write(ended);
    }
    // (bounded: a reader that does not acknowledge in 2 s is not waited for)
    const auto last_word = std::chrono::milliseconds(2000);
    pose_->flush(last_word);
    sim_status_->flush(last_word);
    joints_->flush(last_word);
    tf_->flush(last_word);
    summary();
    return exit_code();
  }

  // The session's end in the exit-code table: a signal or the frame cap ends a session as asked
  // (0), unless convergence was asked to end it (--exit-on-converged): then the cap came first
  int exit_code() const {
    namespace x = common::exit_code;
    const sim::SessionEndReport& end = machine_->session_end();
    switch (end.kind) {
      case sim::SessionEnd::kConverged: return x::kDone;
      case sim::SessionEnd::kServoStopped: return end.reason.rfind("diverging", 0) == 0 ? x::kDiverged : x::kStopped;
      case sim::SessionEnd::kRobotStopped: return x::kStopped;
      case sim::SessionEnd::kStepCap: return x::kCapped;
      case sim::SessionEnd::kFrameCap: return o_.exit_on_converged || o_.exit_on_stop ? x::kCapped : x::kDone;
      case sim::SessionEnd::kNone: break;
    }
    return x::kDone;
  }

 private:
  static sim::CellOptions cell_params(const ServiceOptions& o) {
    sim::CellOptions cp;
    cp.timing = o.mode == TimingMode::kLockstep ? sim::Timing::kLockstep : sim::Timing::kRealtime;
    cp.watchdog_s = o.watchdog_ms / 1e3;
    cp.republish_s = o.republish_ms / 1e3;
    cp.max_frames = o.max_frames;
    cp.exit_on_converged = o.exit_on_converged || o.exit_on_stop;
    cp.exit_on_stop = o.exit_on_stop;
    return cp;
  }

  // the folder LOAD_SCENARIO may read from
  static std::filesystem::path allowed_scenarios_dir(const ServiceOptions& o) {
    std::error_code ec;
    const std::filesystem::path dir = o.scenarios_dir.empty() ? std::filesystem::absolute(o.scenario).parent_path()
                                                              : o.scenarios_dir;
    const std::filesystem::path allowed = std::filesystem::canonical(dir, ec);
    if (ec || !std::filesystem::is_directory(allowed))
      throw std::runtime_error(dir.string() + ": not a folder (--scenarios)");
    return allowed;
  }

  // the participant, every reader and writer, and the node that names them
  void make_endpoints(const ServiceOptions& o) {
    participant_ = cell_dds::make_participant(cell_dds::participant_options(o, "cellsim", "cellsim"));
    make_writers(o);
    make_readers(o);
    record_writes();
    announce_node(o);
  }

  // what cellsim publishes (the autorun's commands among them)
  void make_writers(const ServiceOptions& o) {
    auto& p = *participant_;
    using cell_dds::Stream;
    image_ = std::make_unique<cell_dds::Writer<sensor_msgs::msg::dds_::Image_PubSubType>>(
        p, topic(cell_dds::kImageTopic), cell_dds::writer_qos(Stream::kFrame));
    if (o.white_frame)
      white_ = std::make_unique<cell_dds::Writer<sensor_msgs::msg::dds_::Image_PubSubType>>(
          p, topic(cell_dds::kWhiteImageTopic), cell_dds::writer_qos(Stream::kFrame));
    info_ = std::make_unique<cell_dds::Writer<sensor_msgs::msg::dds_::CameraInfo_PubSubType>>(
        p, topic(cell_dds::kCameraInfoTopic), cell_dds::writer_qos(Stream::kLatched));
    pose_ = std::make_unique<cell_dds::Writer<geometry_msgs::msg::dds_::PoseStamped_PubSubType>>(
        p, topic(cell_dds::kCameraPoseTopic), cell_dds::writer_qos(Stream::kFrame));
    sim_status_ = std::make_unique<cell_dds::Writer<cell_msgs::msg::dds_::SimStatus_PubSubType>>(
        p, topic(cell_dds::kSimStatusTopic), cell_dds::writer_qos(Stream::kFrame));
    truth_ = std::make_unique<cell_dds::Writer<cell_msgs::msg::dds_::SpotTruthArray_PubSubType>>(
        p, topic(cell_dds::kSpotTruthTopic), cell_dds::writer_qos(Stream::kFrame));
    clock_ = std::make_unique<cell_dds::Writer<rosgraph_msgs::msg::dds_::Clock_PubSubType>>(
        p, topic(cell_dds::kClockTopic), cell_dds::writer_qos(Stream::kClock));
    joints_ = std::make_unique<cell_dds::Writer<sensor_msgs::msg::dds_::JointState_PubSubType>>(
        p, topic(cell_dds::kJointStatesTopic), cell_dds::writer_qos(Stream::kFrame));
    tf_ = std::make_unique<cell_dds::Writer<tf2_msgs::msg::dds_::TFMessage_PubSubType>>(
        p, topic(cell_dds::kTfTopic), cell_dds::writer_qos(Stream::kFrame));
    description_ = std::make_unique<cell_dds::Writer<std_msgs::msg::dds_::String_PubSubType>>(
        p, topic(cell_dds::kRobotDescriptionTopic), cell_dds::writer_qos(Stream::kLatched));
    accepted_ = std::make_unique<cell_dds::Writer<cell_msgs::msg::dds_::SimControl_PubSubType>>(
        p, topic(cell_dds::kAcceptedTopic), cell_dds::writer_qos(Stream::kCommand));
    if (o.autorun)
      control_out_ = std::make_unique<cell_dds::Writer<cell_msgs::msg::dds_::SimControl_PubSubType>>(
          p, topic(cell_dds::kControlTopic), cell_dds::writer_qos(Stream::kCommand));
  }

  // what cellsim hears: twists, commands, the servo's status (and, recording, its spots)
  void make_readers(const ServiceOptions& o) {
    auto& p = *participant_;
    using cell_dds::Stream;
    using cell_record::recorded_reader;
    twist_in_ = recorded_reader<geometry_msgs::msg::dds_::TwistStamped_PubSubType>(
        p, topic(cell_dds::kTwistTopic), Stream::kFrame,
        [this](TwistStamped_&& t) { inbox_.push(inbox_.twists, std::move(t), Inbox::kMaxTwists); }, recorder_.get());
    // every command that reaches the cell, the autorun's own included, is recorded here once
    control_in_ = recorded_reader<cell_msgs::msg::dds_::SimControl_PubSubType>(
        p, topic(cell_dds::kControlTopic), Stream::kCommand,
        [this](SimControl_&& c) { inbox_.push(inbox_.commands, std::move(c), Inbox::kMaxCommands); }, recorder_.get());
    status_in_ = recorded_reader<cell_msgs::msg::dds_::ServoStatus_PubSubType>(
        p, topic(cell_dds::kStatusTopic), Stream::kLatched,
        [this](ServoStatus_&& s) {
          if (s.reason().size() > kMaxReasonBytes) s.reason().resize(kMaxReasonBytes);
          {
            std::lock_guard<std::mutex> l(inbox_.m);
            const auto& st = s.header().stamp();
            const std::uint64_t ns = st.sec() < 0 ? ~0ull : static_cast<std::uint64_t>(st.sec()) * 1000000000ull + st.nanosec();
            if (ns > inbox_.newest_sent_ns || ns + inbox_.kept_window_ns < inbox_.newest_sent_ns) {
              ++inbox_.statuses_refused;
              return;
            }
            inbox_.servo_seen = true;
            if (s.reason().rfind("taught", 0) == 0) inbox_.taught_seen = true;
          }
          inbox_.push(inbox_.statuses, std::move(s), Inbox::kMaxStatuses);
        },
        recorder_.get());
    // the servo's decoded spots: read only to be recorded, with the annotations they make (the
    // live view's /servo/annotations: a recording shows the same in Foxglove; they annotate the
    // images, and are left out with them)
    if (recorder_ && o.record_images) {
      annotations_ = std::make_unique<foxglove::Annotations>([this](const foxglove::Annotations::Drawn& a) {
        recorder_->record<foxglove_msgs::msg::dds_::ImageAnnotations_PubSubType>(
            topic(foxglove::kAnnotationsTopic), cell_dds::Stream::kFrame, a, cell_record::wall_ns());
      });
    }
    if (recorder_)
      spots_in_ = recorded_reader<cell_msgs::msg::dds_::DecodedSpots_PubSubType>(
          p, topic(cell_dds::kSpotsTopic), Stream::kFrame,
          [this](cell_msgs::msg::dds_::DecodedSpots_&& x) {
            if (annotations_) annotations_->on_spots(x);
          },
          recorder_.get());
  }

  void announce_node(const ServiceOptions& o) {
    // every endpoint, the autorun's command writer included (issue 21: `ros2 topic info -v`
    // showed it as _NODE_NAME_UNKNOWN_)
    std::vector<eprosima::fastrtps::rtps::GUID_t> writers{image_->guid(),   info_->guid(),   pose_->guid(),
                                                          sim_status_->guid(), truth_->guid(), clock_->guid(),
                                                          joints_->guid(),  tf_->guid(),     description_->guid(),
                                                          accepted_->guid()};
    if (control_out_) writers.push_back(control_out_->guid());
    if (white_) writers.push_back(white_->guid());
    std::vector<eprosima::fastrtps::rtps::GUID_t> readers{twist_in_->guid(), control_in_->guid(), status_in_->guid()};
    if (spots_in_) readers.push_back(spots_in_->guid());
    node_ = std::make_unique<cell_dds::NodeAnnouncement>(*participant_, "cellsim", readers, writers,
                                                         o.ns.empty() ? std::string("/") : "/" + o.ns);
  }

  // --record: the recording is open before the first latched message goes out
  void open_recording(const ServiceOptions& o) {
    if (o.record.empty()) return;
    cell_record::RecordOptions r;
    r.file = o.record;
    r.images = o.record_images;
    r.image_topic = topic(cell_dds::kImageTopic);
    r.white_image_topic = topic(cell_dds::kWhiteImageTopic);
    recorder_ = std::make_unique<cell_record::Recorder>(
        r, mcap::KeyValues{{"scenario", cell_->scenario.name},
                           {"scenario_file", o.scenario.string()},
                           {"seed", std::to_string(cell_->scenario.seed)},
                           {"timing", o.mode == TimingMode::kLockstep ? "lockstep" : "realtime"},
                           {"images", o.record_images ? "recorded" : "left out (--record-no-images)"}});
  }

  // what cellsim writes, each as it goes out (the autorun's commands are recorded as received)
  void record_writes() {
    using cell_dds::Stream;
    auto* r = recorder_.get();
    cell_record::record_writes(r, *image_, Stream::kFrame);
    if (white_) cell_record::record_writes(r, *white_, Stream::kFrame);
    cell_record::record_writes(r, *info_, Stream::kLatched);
    cell_record::record_writes(r, *pose_, Stream::kFrame);
    cell_record::record_writes(r, *sim_status_, Stream::kFrame);
    cell_record::record_writes(r, *truth_, Stream::kFrame);
    cell_record::record_writes(r, *clock_, Stream::kClock);
    cell_record::record_writes(r, *joints_, Stream::kFrame);
    cell_record::record_writes(r, *tf_, Stream::kFrame);
    cell_record::record_writes(r, *description_, Stream::kLatched);
    cell_record::record_writes(r, *accepted_, Stream::kCommand);
  }

  void open_trace(const ServiceOptions& o) {
    if (!o.trace_dir.empty()) {
      common::make_output_folder(o.trace_dir);
      trace_.open(o.trace_dir / "trace.csv", "trace");
      trace_ << "# scenario " << cell_->scenario.name << ", cellsim serve ("
             << (o.mode == TimingMode::kLockstep ? "lockstep" : "realtime")
             << "), one row per applied step, twists and status from the servo\n";
      // realtime adds the measured processing time of each twist (lockstep has none to
      // measure, and keeps the in-process runner's columns)
      trace_ << sim::kTraceHeader << (o.mode == TimingMode::kRealtime ? ",processing_ms" : "") << "\n"
             << std::setprecision(9);
      trace_.flush();
    }
  }

  // Does what the state machine asked; returns true when the session is over.
  bool carry_out(sim::CellOutput& out) {
    for (const auto& line : out.log) std::fprintf(stderr, "%s\n", line.c_str());
    for (const auto& line : out.refusals) {
      recent_refusals_.push_back(common::printable(line, 300));
      while (recent_refusals_.size() > kRecentRefusals) recent_refusals_.pop_front();
      auto notice = status_between_frames(cell_msgs::msg::dds_::SimStatus_Constants::NOTICE);
      sim_status_->write(notice);
    }
    // what the servo learns a command from: before the frames it brought about
    for (const auto& c : out.accepted) {
      SimControl_ m = wire::control(c);
      accepted_->write(m);
      white_pose_.forget();
    }
    if (out.load) start_load(*out.load);
    for (const auto& f : out.frames) publish_frame(f);
    for (const auto& r : out.trace) record(r);
    return out.done;
  }

  void start_load(const std::filesystem::path& requested) {
    std::filesystem::path file;
    try {
      file = allowed_scenario(requested, allowed_dir_);
    } catch (const std::exception& e) {
      machine_->load_failed(without_quoted_content(e.what()));
      return;
    }
    std::fprintf(stderr, "cellsim: loading %s (status LOADING until it is done)\n", file.c_str());
    loading_ = std::async(std::launch::async, [file] {
      LoadResult r;
      try {
        r.cell = sim::build_cell(sim::load_scenario(file));
        r.robot = sim::make_robot(*r.cell);
      } catch (const std::exception& e) {
        r.cell.reset();
        r.error = without_quoted_content(e.what());
      }
      return r;
    });
    last_loading_status_s_ = -1;
  }

  void finish_load() {
    if (!loading_.valid() || loading_.wait_for(std::chrono::seconds(0)) != std::future_status::ready) return;
    LoadResult r = loading_.get();
    if (!r.cell) {
      machine_->load_failed(r.error);
      return;
    }
    cell_ = std::move(r.cell);
    machine_->loaded(cell_->scenario, std::move(r.robot), cell_->goal_plane);
    {
      // another scenario, another frame period: the window of statuses starts again
      std::lock_guard<std::mutex> l(inbox_.m);
      inbox_.newest_sent_ns = 0;
    }
    announce_conditions(cell_->scenario, o_.mode);
    publish_camera_info();
    publish_description();
  }

  // While a load runs there is no frame: the status says so, ten times a second.
  void publish_loading_status() {
    auto st = status_between_frames(cell_msgs::msg::dds_::SimStatus_Constants::LOADING);
    sim_status_->write(st);
  }

  // why the session ended, in the words of the summary line, rt/sim/status and the trace
  std::string session_end_reason() const {
    const std::string& r = machine_->session_end().reason;
    return !r.empty() ? r : g_stop ? "cellsim stopped by a signal" : "cellsim stopped";
  }

  // A status that belongs to no frame (LOADING, NOTICE, ENDED), stamped with the next frame's.
  cell_msgs::msg::dds_::SimStatus_ status_between_frames(std::uint8_t state) const {
    return wire::status_between_frames(state, *machine_, recent_refusals_);
  }

  double dt() const { return cell_->scenario.dt_s; }

  void publish_camera_info() {
    auto ci = wire::camera_info(cell_->scenario, cell_dds::stamp_of(machine_->next_frame(), dt()));
    info_->write(ci);
  }

  // The URDF, for ROS 2 tools (rviz's RobotModel); latched: late joiners get it.
  void publish_description() {
    auto d = wire::description(cell_->scenario);
    description_->write(d);
  }

  // Frame k: sim status, camera pose (truth), robot, spot truth, image, clock, all with one
  // stamp; the status and the pose before the image (the servo pairs them by stamp).
  void publish_frame(const sim::FrameOrder& f) {
    const auto stamp = cell_dds::stamp_of(f.index, dt());
    {
      std::lock_guard<std::mutex> l(inbox_.m);
      const std::uint64_t ns = static_cast<std::uint64_t>(stamp.sec()) * 1000000000ull + stamp.nanosec();
      inbox_.newest_sent_ns = std::max(inbox_.newest_sent_ns, ns);
      inbox_.kept_window_ns = static_cast<std::uint64_t>(std::llround(dt() * 1e9)) * sim::CellStateMachine::kMaxKeptStatuses;
    }
    // the scene the image shows (a frame ago or more, with an acquisition delay)
    const std::uint64_t seed = sim::frame_seed(cell_->scenario.seed, f.index);
    const cv::Mat rgb = sim::render_image(*cell_, f.scene_world_T_camera, seed, &scratch_, nullptr, &f.scene_world_T_links);
    auto st = wire::frame_status(f, *machine_, stamp, recent_refusals_);
    sim_status_->write(st);
    if (annotations_) annotations_->on_status(st);
    auto pose = wire::camera_pose(f, stamp);
    pose_->write(pose);
    auto tf = wire::transforms(cell_->scenario, f, stamp);
    tf_->write(tf);
    if (wire::has_joints(cell_->scenario, f)) {
      auto js = wire::joint_state(f, stamp);
      joints_->write(js);
    }
    if (truth_->matched() > 0) {  // 400 visibility rays: only when someone listens
      auto truth = wire::spot_truth(*cell_, f, stamp);
      truth_->write(truth);
    }
    if (white_) {  // where the camera took it (sim::WhiteFramePose), its own noise draw, as in-process
      auto white = wire::image(sim::render_image(*cell_, white_pose_.at(f), sim::white_frame_seed(seed), &scratch_,
                                                 nullptr, &f.scene_world_T_links, sim::Cast::kWhite),
                               stamp);
      white_->write(white);
    }
    auto img = wire::image(rgb, stamp);
    image_->write(img);
    auto clk = wire::clock(stamp);
    clock_->write(clk);
  }

  void record(const sim::TraceRow& r) {
    if (!trace_.is_open()) return;
    sim::write_trace_row(trace_, r, o_.mode == TimingMode::kRealtime);
    if (o_.mode == TimingMode::kRealtime) trace_.flush();  // a realtime run usually ends by a signal
  }

  void summary() {
    const auto& c = machine_->counters();
    const Eigen::Isometry3d wTc = machine_->world_T_camera();
    if (c.applied > 0 && c.stepping_s > 0)
      std::printf("cellsim: loop rate %.0f iterations/s (%ld steps in %.2f s of stepping time; idle and paused time "
                  "not counted)\n",
                  c.applied / c.stepping_s, c.applied, c.stepping_s);
    long dropped;
    {
      std::lock_guard<std::mutex> l(inbox_.m);
      dropped = inbox_.dropped;
    }
    const sim::GoalError goal = sim::goal_error(wTc, cell_->scenario.world_T_desired, cell_->goal_plane);
    std::printf("cellsim: %ld frames, %ld twists applied, rejected %ld NaN/Inf, %ld wrong frame, %ld stale, %ld out of "
                "the workspace; %ld late answers (to frames already stepped); %ld watchdog stops; %ld robot stops "
                "(collision); %ld commands (%ld refused); %ld inputs dropped; final error %.3f mm, %.4f deg\n",
                c.frames, c.applied, c.rejected_nan, c.rejected_frame, c.rejected_stale, c.rejected_workspace,
                c.late_answers, c.watchdog_stops, c.robot_stops, c.commands, c.commands_refused, dropped + c.dropped_inputs,
                1e3 * goal.translation_m, goal.rotation_rad * 180.0 / 3.14159265358979323846);
    const std::string end = session_end_reason();
    std::printf("cellsim: session ended: %s\n", end.c_str());
    if (trace_.is_open()) trace_ << "# session ended: " << end << '\n' << std::flush;
    try {
      trace_.close();
    } catch (const common::FileError& e) {  // said; the recording below is still closed whole
      std::fprintf(stderr, "cellsim: %s\n", e.what());
    }
    if (recorder_) {
      // the recording's path, size and what it holds per topic (what an MCAP reader must find)
      const mcap::WriteSummary w = recorder_->close();
      std::printf("cellsim: recorded %s\n", recorder_->describe(w).c_str());
      std::printf("cellsim: recorded messages: %s\n", cell_record::Recorder::topic_counts(w).c_str());
    }
    std::fflush(stdout);
  }

  std::string topic(const char* t) const { return cell_dds::namespaced(o_.ns, t); }
  ServiceOptions o_;
  std::filesystem::path allowed_dir_;
  std::future<LoadResult> loading_;
  double last_loading_status_s_ = -1;
  std::unique_ptr<sim::Cell> cell_;
  std::unique_ptr<sim::CellStateMachine> machine_;
  sim::RenderScratch scratch_;
  Inbox inbox_;
  common::OutputStream trace_;
  // before the participant: destroyed after every endpoint that records into it
  std::unique_ptr<cell_record::Recorder> recorder_;
  // the annotations recorded beside the spots (with --record), fed by the spots' reader
  std::unique_ptr<foxglove::Annotations> annotations_;
  cell_dds::ParticipantPtr participant_;
  // the live view's readers of this cell's own topics (--foxglove), gone before the participant
  std::unique_ptr<foxglove::Bridge> live_;
  std::unique_ptr<cell_dds::Writer<sensor_msgs::msg::dds_::Image_PubSubType>> image_;
  std::unique_ptr<cell_dds::Writer<sensor_msgs::msg::dds_::Image_PubSubType>> white_;  // --white-frame
  sim::WhiteFramePose white_pose_{o_.white_frame_lead};  // declared after o_, which it is made from
  std::unique_ptr<cell_dds::Writer<sensor_msgs::msg::dds_::CameraInfo_PubSubType>> info_;
  std::unique_ptr<cell_dds::Writer<geometry_msgs::msg::dds_::PoseStamped_PubSubType>> pose_;
  std::unique_ptr<cell_dds::Writer<cell_msgs::msg::dds_::SimStatus_PubSubType>> sim_status_;
  std::unique_ptr<cell_dds::Writer<cell_msgs::msg::dds_::SpotTruthArray_PubSubType>> truth_;
  std::unique_ptr<cell_dds::Writer<rosgraph_msgs::msg::dds_::Clock_PubSubType>> clock_;
  std::unique_ptr<cell_dds::Writer<sensor_msgs::msg::dds_::JointState_PubSubType>> joints_;
  std::unique_ptr<cell_dds::Writer<tf2_msgs::msg::dds_::TFMessage_PubSubType>> tf_;
  std::unique_ptr<cell_dds::Writer<std_msgs::msg::dds_::String_PubSubType>> description_;
  std::unique_ptr<cell_dds::Writer<cell_msgs::msg::dds_::SimControl_PubSubType>> control_out_;
  std::unique_ptr<cell_dds::Writer<cell_msgs::msg::dds_::SimControl_PubSubType>> accepted_;  // rt/sim/accepted
  static constexpr std::size_t kMaxReasonBytes = 256;  // of a received status's reason: what the summary shows
  // the latest refusals, as rt/sim/status says them (the IDL's bound)
  static constexpr std::size_t kRecentRefusals = 8;
  std::deque<std::string> recent_refusals_;
  std::unique_ptr<cell_dds::Reader<geometry_msgs::msg::dds_::TwistStamped_PubSubType>> twist_in_;
  std::unique_ptr<cell_dds::Reader<cell_msgs::msg::dds_::SimControl_PubSubType>> control_in_;
  std::unique_ptr<cell_dds::Reader<cell_msgs::msg::dds_::ServoStatus_PubSubType>> status_in_;
  std::unique_ptr<cell_dds::Reader<cell_msgs::msg::dds_::DecodedSpots_PubSubType>> spots_in_;
  std::unique_ptr<cell_dds::NodeAnnouncement> node_;
};

}  // namespace

int run_sim_service(const ServiceOptions& options) {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::signal(SIGHUP, on_signal);  // a closed terminal or ssh session: stop as cleanly as on Ctrl-C
  SimService service(options);
  return service.run();
}

}  // namespace sim
