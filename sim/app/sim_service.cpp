#include "sim/app/sim_service.hpp"

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <deque>
#include <fstream>
#include <iomanip>
#include <mutex>
#include <optional>
#include <thread>

#include "cell_msgsPubSubTypes.h"
#include "dds/endpoint.hpp"
#include "dds/topics.hpp"
#include "geometry_msgsPubSubTypes.h"
#include "rosgraph_msgsPubSubTypes.h"
#include "sensor_msgsPubSubTypes.h"
#include "sim/geometry/se3.hpp"
#include "sim/render/renderer.hpp"
#include "sim/robot/robot.hpp"

namespace cellsim {
namespace {

using Clock = std::chrono::steady_clock;
using geometry_msgs::msg::dds_::TwistStamped_;
using cell_msgs::msg::dds_::ServoStatus_;
using cell_msgs::msg::dds_::SimControl_;
namespace SC = cell_msgs::msg::dds_::SimControl_Constants;
namespace SS = cell_msgs::msg::dds_::ServoStatus_Constants;

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

// Everything the DDS listener threads hand to the service loop.
struct Inbox {
  std::mutex m;
  std::condition_variable cv;
  std::deque<TwistStamped_> twists;
  std::deque<SimControl_> commands;
  std::deque<ServoStatus_> statuses;
  void notify() { cv.notify_all(); }
};

struct Counters {
  long frames = 0, applied = 0, rejected_nan = 0, rejected_frame = 0, rejected_stale = 0, watchdog_stops = 0;
};

class SimService {
 public:
  explicit SimService(const ServiceOptions& o) : o_(o) {
    load(o.scenario);
    cell_dds::ParticipantOptions po;
    po.domain_id = o.domain_id;
    po.name = "cellsim";
    participant_ = cell_dds::make_participant(po);
    auto& p = *participant_;
    using cell_dds::Stream;
    image_ = std::make_unique<cell_dds::Writer<sensor_msgs::msg::dds_::Image_PubSubType>>(
        p, cell_dds::kImageTopic, cell_dds::writer_qos(Stream::kFrame));
    info_ = std::make_unique<cell_dds::Writer<sensor_msgs::msg::dds_::CameraInfo_PubSubType>>(
        p, cell_dds::kCameraInfoTopic, cell_dds::writer_qos(Stream::kLatched));
    pose_ = std::make_unique<cell_dds::Writer<geometry_msgs::msg::dds_::PoseStamped_PubSubType>>(
        p, cell_dds::kCameraPoseTopic, cell_dds::writer_qos(Stream::kFrame));
    truth_ = std::make_unique<cell_dds::Writer<cell_msgs::msg::dds_::SpotTruthArray_PubSubType>>(
        p, cell_dds::kSpotTruthTopic, cell_dds::writer_qos(Stream::kFrame));
    clock_ = std::make_unique<cell_dds::Writer<rosgraph_msgs::msg::dds_::Clock_PubSubType>>(
        p, cell_dds::kClockTopic, cell_dds::writer_qos(Stream::kClock));
    twist_in_ = std::make_unique<cell_dds::Reader<geometry_msgs::msg::dds_::TwistStamped_PubSubType>>(
        p, cell_dds::kTwistTopic, cell_dds::reader_qos(Stream::kFrame), [this](TwistStamped_&& t) {
          std::lock_guard<std::mutex> l(inbox_.m);
          inbox_.twists.push_back(std::move(t));
          inbox_.notify();
        });
    control_in_ = std::make_unique<cell_dds::Reader<cell_msgs::msg::dds_::SimControl_PubSubType>>(
        p, cell_dds::kControlTopic, cell_dds::reader_qos(Stream::kCommand), [this](SimControl_&& c) {
          std::lock_guard<std::mutex> l(inbox_.m);
          inbox_.commands.push_back(std::move(c));
          inbox_.notify();
        });
    status_in_ = std::make_unique<cell_dds::Reader<cell_msgs::msg::dds_::ServoStatus_PubSubType>>(
        p, cell_dds::kStatusTopic, cell_dds::reader_qos(Stream::kLatched), [this](ServoStatus_&& s) {
          std::lock_guard<std::mutex> l(inbox_.m);
          inbox_.statuses.push_back(std::move(s));
          inbox_.notify();
        });
    publish_camera_info();
    if (!o.trace_dir.empty()) {
      std::filesystem::create_directories(o.trace_dir);
      trace_.open(o.trace_dir / "trace.csv");
      if (!trace_) throw std::runtime_error((o.trace_dir / "trace.csv").string() + ": cannot write");
      trace_ << "# scenario " << cell_->scenario.name << ", cellsim serve ("
             << (o.mode == TimingMode::kLockstep ? "lockstep" : "realtime") << "), twists and status from the servo\n";
      trace_ << "t,vx,vy,vz,wx,wy,wz,error_norm,decoded,matched,translation_error_m,rotation_error_deg\n"
             << std::setprecision(9);
    }
  }

  int run() {
    std::printf("cellsim: ready (scenario %s, %s, domain %d)\n", cell_->scenario.name.c_str(),
                o_.mode == TimingMode::kLockstep ? "lockstep" : "realtime", o_.domain_id);
    std::fflush(stdout);
    if (o_.autorun) autorun();
    int code = o_.mode == TimingMode::kLockstep ? lockstep() : realtime();
    summary();
    return code;
  }

 private:
  void load(const std::filesystem::path& file) {
    cell_ = sim::build_cell(sim::load_scenario(file));
    robot_ = std::make_unique<sim::FreeFlyingCamera>(cell_->scenario.world_T_desired, cell_->scenario.robot.max_linear_mps,
                                                     cell_->scenario.robot.max_angular_radps);
    frame_ = 0;
  }

  double dt() const { return cell_->scenario.dt_s; }

  void publish_camera_info() {
    const auto& k = cell_->scenario.camera.intrinsics;
    sensor_msgs::msg::dds_::CameraInfo_ ci;
    ci.header().stamp(cell_dds::stamp_of(frame_, dt()));
    ci.header().frame_id(cell_dds::kCameraFrame);
    ci.height(static_cast<uint32_t>(k.height));
    ci.width(static_cast<uint32_t>(k.width));
    ci.distortion_model("plumb_bob");
    const auto& d = cell_->scenario.camera.distortion;
    ci.d(std::vector<double>(d.begin(), d.end()));
    ci.k({k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1});
    ci.r({1, 0, 0, 0, 1, 0, 0, 0, 1});
    ci.p({k.fx, 0, k.cx, 0, 0, k.fy, k.cy, 0, 0, 0, 1, 0});
    info_->write(ci);
  }

  void publish_truth(const builtin_interfaces::msg::dds_::Time_& stamp, const Eigen::Isometry3d& wTc) {
    cell_msgs::msg::dds_::SpotTruthArray_ truth;
    truth.header().stamp(stamp);
    truth.header().frame_id(cell_dds::kCameraFrame);
    for (const auto& t : sim::compute_truth(*cell_, wTc)) {
      cell_msgs::msg::dds_::SpotTruth_ s;
      s.row(static_cast<int16_t>(t.row));
      s.col(static_cast<int16_t>(t.col));
      s.visible(t.visible);
      s.u(t.uv.x());
      s.v(t.uv.y());
      s.depth_m(t.depth_m);
      truth.spots().push_back(s);
    }
    truth_->write(truth);
  }

  // Frame k: image, camera pose (truth), spot truth, clock, all with the same stamp.
  void publish_frame() {
    const auto stamp = cell_dds::stamp_of(frame_, dt());
    const Eigen::Isometry3d wTc = robot_->world_T_camera();
    const cv::Mat rgb = sim::render_image(*cell_, wTc, sim::frame_seed(cell_->scenario.seed, frame_), &scratch_);

    geometry_msgs::msg::dds_::PoseStamped_ pose;
    pose.header().stamp(stamp);
    pose.header().frame_id(cell_dds::kWorldFrame);
    const Eigen::Quaterniond q(wTc.rotation());
    pose.pose().position().x(wTc.translation().x());
    pose.pose().position().y(wTc.translation().y());
    pose.pose().position().z(wTc.translation().z());
    pose.pose().orientation().x(q.x());
    pose.pose().orientation().y(q.y());
    pose.pose().orientation().z(q.z());
    pose.pose().orientation().w(q.w());
    pose_->write(pose);  // before the image: the servo may need it to triangulate

    if (truth_->matched() > 0) publish_truth(stamp, wTc);  // 400 visibility rays: only when someone listens

    sensor_msgs::msg::dds_::Image_ img;
    img.header().stamp(stamp);
    img.header().frame_id(cell_dds::kCameraFrame);
    img.height(static_cast<uint32_t>(rgb.rows));
    img.width(static_cast<uint32_t>(rgb.cols));
    img.encoding("rgb8");
    img.is_bigendian(0);
    img.step(static_cast<uint32_t>(rgb.cols * 3));
    img.data().assign(rgb.data, rgb.data + rgb.total() * 3);
    image_->write(img);

    rosgraph_msgs::msg::dds_::Clock_ clk;
    clk.clock(stamp);
    clock_->write(clk);
    ++counters_.frames;
  }

  // A twist is applied only when finite, in the camera frame, and answering the frame it
  // must answer (lockstep: exactly frame k; realtime: no older than the last one applied).
  std::optional<sim::Vector6d> validate(const TwistStamped_& t, bool lockstep) {
    const auto& l = t.twist().linear();
    const auto& a = t.twist().angular();
    sim::Vector6d v;
    v << l.x(), l.y(), l.z(), a.x(), a.y(), a.z();
    if (!v.allFinite()) {
      ++counters_.rejected_nan;
      std::fprintf(stderr, "cellsim: rejected a twist with NaN/Inf (stamp %.3f s)\n", cell_dds::seconds(t.header().stamp()));
      return std::nullopt;
    }
    if (t.header().frame_id() != cell_dds::kCameraFrame) {
      ++counters_.rejected_frame;
      std::fprintf(stderr, "cellsim: rejected a twist in frame '%s' (expected %s)\n", t.header().frame_id().c_str(),
                   cell_dds::kCameraFrame);
      return std::nullopt;
    }
    const std::uint64_t k = cell_dds::frame_of(t.header().stamp(), dt());
    const bool fresh = lockstep ? k == frame_ : (k <= frame_ && (!last_applied_ || k >= *last_applied_));
    if (!fresh) {
      ++counters_.rejected_stale;
      return std::nullopt;
    }
    last_applied_ = k;
    return v;
  }

  // Commands from rt/sim/control. Returns false to leave the loop.
  void handle(const SimControl_& c) {
    switch (c.command()) {
      case SC::LOAD_SCENARIO:
        try {
          load(c.argument());
          publish_camera_info();
          running_ = false;
          std::printf("cellsim: loaded %s\n", c.argument().c_str());
        } catch (const std::exception& e) {
          std::fprintf(stderr, "cellsim: LOAD_SCENARIO refused: %s\n", e.what());
        }
        break;
      case SC::RESET:
        try {
          robot_->reset(sim::resolve_pose(cell_->scenario, c.argument().empty() ? "initial" : c.argument()));
          running_ = false;
        } catch (const std::exception& e) {
          std::fprintf(stderr, "cellsim: RESET refused: %s\n", e.what());
        }
        break;
      case SC::TEACH:
        robot_->reset(cell_->scenario.world_T_desired);
        running_ = false;
        pending_steps_ = 1;  // one frame for the servo to teach from
        break;
      case SC::START: running_ = true; break;
      case SC::PAUSE: running_ = false; break;
      case SC::STEP: pending_steps_ += std::max<uint32_t>(1, c.steps()); break;
      default: std::fprintf(stderr, "cellsim: unknown control command %d ignored\n", c.command());
    }
  }

  // --autorun: the sequence an external client would send, sent on rt/sim/control so the
  // servo hears it too (and this service's own reader receives it like any other).
  void autorun() {
    cell_dds::Writer<cell_msgs::msg::dds_::SimControl_PubSubType> control(*participant_, cell_dds::kControlTopic,
                                                                           cell_dds::writer_qos(cell_dds::Stream::kCommand));
    // wait (bounded, 20 ms naps) for a servo: our own reader plus at least one other
    const auto until = Clock::now() + std::chrono::seconds(60);
    while (!g_stop && (control.matched() < 2 || image_->matched() == 0 || twist_in_->matched() == 0) &&
           Clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (control.matched() < 2) std::fprintf(stderr, "cellsim: autorun: no servo found after 60 s, starting anyway\n");
    for (auto [c, arg] : {std::pair<uint8_t, const char*>{SC::TEACH, ""}, {SC::RESET, "initial"}, {SC::START, ""}}) {
      SimControl_ s;
      s.command(c);
      s.argument(arg);
      control.write(s);
    }
    // the writer goes out of scope: let reliable delivery finish first
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }

  void drain(std::unique_lock<std::mutex>& lock) {
    while (!inbox_.commands.empty()) {
      SimControl_ c = std::move(inbox_.commands.front());
      inbox_.commands.pop_front();
      // the servo hears the same command; give it the teach frame with nothing else queued
      if (c.command() == SC::TEACH && pending_steps_ > 0) {
        inbox_.commands.push_front(std::move(c));
        return;
      }
      lock.unlock();
      handle(c);
      lock.lock();
      if (c.command() == SC::TEACH) return;  // publish the teach frame before the next command
    }
  }

  bool converged_seen(std::unique_lock<std::mutex>&) {
    for (const auto& s : inbox_.statuses) if (s.state() == SS::CONVERGED) return true;
    return false;
  }

  std::optional<ServoStatus_> status_for(std::uint64_t k) {
    for (auto it = inbox_.statuses.rbegin(); it != inbox_.statuses.rend(); ++it)
      if (cell_dds::frame_of(it->header().stamp(), dt()) == k) return *it;
    return std::nullopt;
  }

  void record(std::uint64_t frame, const sim::Vector6d& v, const std::optional<ServoStatus_>& st,
              const Eigen::Isometry3d& wTc) {
    if (!trace_.is_open()) return;
    trace_ << (frame - first_run_frame_) * dt();
    for (int i = 0; i < 6; ++i) trace_ << ',' << v[i];
    trace_ << ',' << (st ? st->error_norm() : std::nan("")) << ',' << (st ? st->decoded() : 0) << ','
           << (st ? st->matched() : 0) << ',' << sim::translation_error(wTc, cell_->scenario.world_T_desired) << ','
           << sim::rotation_error(wTc, cell_->scenario.world_T_desired) * 180.0 / 3.14159265358979323846 << '\n';
  }

  int lockstep() {
    std::unique_lock<std::mutex> lock(inbox_.m);
    while (!g_stop) {
      drain(lock);
      const bool stepping = running_ || pending_steps_ > 0;
      if (!stepping) {
        inbox_.cv.wait_for(lock, std::chrono::milliseconds(50));
        continue;
      }
      if (o_.max_frames > 0 && counters_.frames >= o_.max_frames) break;
      const bool teaching_frame = !running_;
      if (running_ && !run_started_) {
        run_started_ = true;
        first_run_frame_ = frame_;
        run_start_ = Clock::now();
      }
      // publish frame k and wait for its twist; unanswered frames are sent again
      lock.unlock();
      publish_frame();
      lock.lock();
      auto sent = Clock::now();
      std::optional<sim::Vector6d> v;
      while (!g_stop && !v) {
        while (!inbox_.twists.empty() && !v) {
          TwistStamped_ t = std::move(inbox_.twists.front());
          inbox_.twists.pop_front();
          v = validate(t, true);
        }
        if (v) break;
        // a command (pause, reset, load) wins over a running frame; the teach frame must be
        // answered first (the servo takes s* from it)
        if (!inbox_.commands.empty() && !teaching_frame) break;
        if (Clock::now() - sent > std::chrono::duration<double, std::milli>(o_.republish_ms)) {
          ++counters_.watchdog_stops;
          lock.unlock();
          publish_frame();  // the same frame k again: a restarted servo picks the run up
          --counters_.frames;
          lock.lock();
          sent = Clock::now();
        }
        inbox_.cv.wait_for(lock, std::chrono::milliseconds(20));
      }
      if (!v) continue;
      // The servo's status for this frame travels on another topic and may land after the
      // twist: the trace row is written once it is here, at the latest one frame later.
      flush_pending(lock, false);
      const Eigen::Isometry3d wTc = robot_->world_T_camera();
      const std::optional<ServoStatus_> st = status_for(frame_);
      if (!teaching_frame) {
        pending_ = Pending{frame_, *v, wTc};
        flush_pending(lock, false);
        robot_->apply_twist(*v, dt());
        ++counters_.applied;
      }
      ++frame_;
      if (pending_steps_ > 0) --pending_steps_;
      if (o_.exit_on_converged && st && st->state() == SS::CONVERGED) break;
      if (o_.exit_on_converged && converged_seen(lock)) break;
      if (inbox_.statuses.size() > 64) inbox_.statuses.erase(inbox_.statuses.begin(), inbox_.statuses.end() - 8);
    }
    flush_pending(lock, true);
    return 0;
  }

  // Writes the pending trace row when its frame's status has arrived (or, at the end, after a
  // short bounded wait for it).
  void flush_pending(std::unique_lock<std::mutex>& lock, bool final) {
    if (!pending_) return;
    std::optional<ServoStatus_> st = status_for(pending_->frame);
    for (int i = 0; final && !st && i < 20; ++i) {
      inbox_.cv.wait_for(lock, std::chrono::milliseconds(5));
      st = status_for(pending_->frame);
    }
    if (!st && !final) return;
    record(pending_->frame, pending_->twist, st, pending_->world_T_camera);
    pending_.reset();
  }

  int realtime() {
    const auto period = std::chrono::duration<double>(dt());
    auto next = Clock::now();
    Clock::time_point last_valid = Clock::now() - std::chrono::hours(1);
    sim::Vector6d current = sim::Vector6d::Zero();
    std::unique_lock<std::mutex> lock(inbox_.m);
    while (!g_stop) {
      drain(lock);
      if (o_.max_frames > 0 && counters_.frames >= o_.max_frames) break;
      // commands apply on arrival; the newest valid twist drives the robot until it goes stale
      while (!inbox_.twists.empty()) {
        TwistStamped_ t = std::move(inbox_.twists.front());
        inbox_.twists.pop_front();
        if (auto v = validate(t, false)) {
          current = *v;
          last_valid = Clock::now();
        }
      }
      const bool fresh = Clock::now() - last_valid < std::chrono::duration<double, std::milli>(o_.watchdog_ms);
      if (!fresh && current.norm() > 0) {
        ++counters_.watchdog_stops;
        std::fprintf(stderr, "cellsim: watchdog: no valid twist for %.0f ms, robot stopped\n", o_.watchdog_ms);
        current.setZero();
      }
      const bool moving = running_ || pending_steps_ > 0;
      lock.unlock();
      if (moving) {
        robot_->apply_twist(current, dt());
        ++counters_.applied;
      }
      publish_frame();
      ++frame_;
      lock.lock();
      if (pending_steps_ > 0) --pending_steps_;
      if (o_.exit_on_converged && converged_seen(lock)) break;
      inbox_.statuses.clear();
      next += std::chrono::duration_cast<Clock::duration>(period);
      inbox_.cv.wait_until(lock, next, [] { return g_stop.load(); });
    }
    return 0;
  }

  void summary() {
    const Eigen::Isometry3d wTc = robot_->world_T_camera();
    if (run_started_ && counters_.applied > 0) {
      const double secs = std::chrono::duration<double>(Clock::now() - run_start_).count();
      std::printf("cellsim: loop rate %.0f iterations/s (%ld steps in %.2f s of wall time, after teaching)\n",
                  counters_.applied / secs, counters_.applied, secs);
    }
    std::printf("cellsim: %ld frames, %ld twists applied, rejected %ld NaN/Inf, %ld wrong frame, %ld stale; %ld "
                "watchdog stops; final error %.3f mm, %.4f deg\n",
                counters_.frames, counters_.applied, counters_.rejected_nan, counters_.rejected_frame,
                counters_.rejected_stale, counters_.watchdog_stops,
                1e3 * sim::translation_error(wTc, cell_->scenario.world_T_desired),
                sim::rotation_error(wTc, cell_->scenario.world_T_desired) * 180.0 / 3.14159265358979323846);
    std::fflush(stdout);
  }

  ServiceOptions o_;
  std::unique_ptr<sim::Cell> cell_;
  std::unique_ptr<sim::FreeFlyingCamera> robot_;
  sim::RenderScratch scratch_;
  std::uint64_t frame_ = 0, first_run_frame_ = 0;
  std::optional<std::uint64_t> last_applied_;
  struct Pending {
    std::uint64_t frame;
    sim::Vector6d twist;
    Eigen::Isometry3d world_T_camera;
  };
  std::optional<Pending> pending_;  // the last applied step, its trace row not yet written
  bool running_ = false, run_started_ = false;
  Clock::time_point run_start_;
  unsigned pending_steps_ = 0;
  Counters counters_;
  Inbox inbox_;
  std::ofstream trace_;
  cell_dds::ParticipantPtr participant_;
  std::unique_ptr<cell_dds::Writer<sensor_msgs::msg::dds_::Image_PubSubType>> image_;
  std::unique_ptr<cell_dds::Writer<sensor_msgs::msg::dds_::CameraInfo_PubSubType>> info_;
  std::unique_ptr<cell_dds::Writer<geometry_msgs::msg::dds_::PoseStamped_PubSubType>> pose_;
  std::unique_ptr<cell_dds::Writer<cell_msgs::msg::dds_::SpotTruthArray_PubSubType>> truth_;
  std::unique_ptr<cell_dds::Writer<rosgraph_msgs::msg::dds_::Clock_PubSubType>> clock_;
  std::unique_ptr<cell_dds::Reader<geometry_msgs::msg::dds_::TwistStamped_PubSubType>> twist_in_;
  std::unique_ptr<cell_dds::Reader<cell_msgs::msg::dds_::SimControl_PubSubType>> control_in_;
  std::unique_ptr<cell_dds::Reader<cell_msgs::msg::dds_::ServoStatus_PubSubType>> status_in_;
};

}  // namespace

int run_sim_service(const ServiceOptions& options) {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  SimService service(options);
  return service.run();
}

}  // namespace cellsim
