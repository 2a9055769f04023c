#include "servo/service/servo_service.hpp"

#include "common/output_file.hpp"
#include "common/regular_file.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <deque>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>

#include "cell_msgsPubSubTypes.h"
#include "dds/endpoint.hpp"
#include "dds/ros_graph.hpp"
#include "dds/cli_flags.hpp"
#include "dds/topics.hpp"
#include "geometry_msgsPubSubTypes.h"
#include "sensor_msgsPubSubTypes.h"
#include "common/strict_yaml.hpp"
#include "servo/messages/servo_messages.hpp"
#include "servo/node/servo_state_machine.hpp"
#include "servo/pattern/pattern_file.hpp"

namespace servo {
namespace {

using Clock = std::chrono::steady_clock;
using sensor_msgs::msg::dds_::Image_;
using sensor_msgs::msg::dds_::CameraInfo_;
using geometry_msgs::msg::dds_::PoseStamped_;
using cell_msgs::msg::dds_::SimControl_;
using cell_msgs::msg::dds_::SimStatus_;

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

void save_reference(const std::filesystem::path& file, const std::vector<control::Feature>& s) {
  nlohmann::json j = nlohmann::json::array();
  for (const auto& f : s) {
    nlohmann::json e{{"row", f.row}, {"col", f.col}, {"x", f.x}, {"y", f.y}};
    e["z"] = f.z ? nlohmann::json(*f.z) : nlohmann::json(nullptr);
    j.push_back(e);
  }
  common::write_output_file(file, j.dump(1) + "\n", "reference");
}

}  // namespace

std::vector<control::Feature> load_reference(const std::filesystem::path& file) {
  const std::string text = common::read_regular_file(file, 16u << 20, "reference file");
  std::vector<control::Feature> out;
  try {
    const nlohmann::json j = nlohmann::json::parse(text);
    if (!j.is_array() || j.size() > 65536) throw std::runtime_error("expected a list of at most 65536 features");
    for (const auto& e : j) {
      control::Feature f{e.at("row").get<int>(), e.at("col").get<int>(), e.at("x").get<double>(), e.at("y").get<double>(),
                         std::nullopt, std::nullopt};
      if (!e.at("z").is_null()) f.z = e.at("z").get<double>();
      if (!std::isfinite(f.x) || !std::isfinite(f.y) || (f.z && !(std::isfinite(*f.z) && *f.z > 0)))
        throw std::runtime_error("non-finite feature or non-positive depth");
      if (f.row < 0 || f.col < 0 || f.row >= pattern::kMaxPatternSide || f.col >= pattern::kMaxPatternSide)
        throw std::runtime_error("spot id outside the pattern");
      out.push_back(f);
    }
  } catch (const std::exception& e) {
    throw std::runtime_error(file.string() + ": not a reference file (JSON list of features): " +
                             common::printable(e.what(), 200));
  }
  return out;
}

namespace {

// What the DDS listener threads hand to the service loop; every queue bounded.
struct Inbox {
  static constexpr std::size_t kMaxImages = 2, kMaxWhites = 4, kMaxCommands = 64, kMaxFrameInfo = 16;
  std::mutex m;
  std::condition_variable cv;
  std::deque<Image_> images;  // realtime: never queue stale frames
  // --white-frame: the white reference frames, each sent before the image of its stamp; a few,
  // so that realtime's newest image finds its own among those of images dropped before it
  std::deque<Image_> whites;
  bool white_seen = false;
  std::deque<SimControl_> commands;
  std::deque<PoseStamped_> poses;
  std::deque<SimStatus_> sim_statuses;
  std::optional<CameraInfo_> info;
  bool info_fresh = false;
  template <typename T>
  void push(std::deque<T>& q, T&& v, std::size_t max) {
    std::lock_guard<std::mutex> l(m);
    if (q.size() >= max) q.pop_front();
    q.push_back(std::move(v));
    cv.notify_all();
  }
};

class ServoService {
 public:
  explicit ServoService(const ServiceOptions& o) : o_(o) {
    std::error_code ec;
    auto pipeline = make_pipeline(o.pattern, o.config, std::filesystem::exists(o.reference, ec) ? o.reference : "");
    if (pipeline->taught())
      std::printf("servo: reference loaded from %s (%zu features)\n", o.reference.c_str(), pipeline->reference().size());
    else if (!o.reference.empty())
      common::check_output_file(o.reference, "reference");  // a link in its place is said now, not after teaching
    machine_ = std::make_unique<ServoStateMachine>(std::move(pipeline), ServoTiming{o.lost_ms / 1e3, o.autostart});
    participant_ = cell_dds::make_participant(cell_dds::participant_options(o, "servo", "servo"));
    auto& p = *participant_;
    using cell_dds::Stream;
    twist_ = std::make_unique<cell_dds::Writer<geometry_msgs::msg::dds_::TwistStamped_PubSubType>>(
        p, topic(cell_dds::kTwistTopic), cell_dds::writer_qos(Stream::kFrame));
    spots_ = std::make_unique<cell_dds::Writer<cell_msgs::msg::dds_::DecodedSpots_PubSubType>>(
        p, topic(cell_dds::kSpotsTopic), cell_dds::writer_qos(Stream::kFrame));
    status_ = std::make_unique<cell_dds::Writer<cell_msgs::msg::dds_::ServoStatus_PubSubType>>(
        p, topic(cell_dds::kStatusTopic), cell_dds::writer_qos(Stream::kLatched));
    image_in_ = std::make_unique<cell_dds::Reader<sensor_msgs::msg::dds_::Image_PubSubType>>(
        p, topic(cell_dds::kImageTopic), cell_dds::reader_qos(Stream::kFrame),
        [this](Image_&& i) { in_.push(in_.images, std::move(i), Inbox::kMaxImages); });
    info_in_ = std::make_unique<cell_dds::Reader<sensor_msgs::msg::dds_::CameraInfo_PubSubType>>(
        p, topic(cell_dds::kCameraInfoTopic), cell_dds::reader_qos(Stream::kLatched), [this](CameraInfo_&& c) {
          std::lock_guard<std::mutex> l(in_.m);
          in_.info = std::move(c);
          in_.info_fresh = true;
        });
    pose_in_ = std::make_unique<cell_dds::Reader<geometry_msgs::msg::dds_::PoseStamped_PubSubType>>(
        p, topic(cell_dds::kCameraPoseTopic), cell_dds::reader_qos(Stream::kFrame),
        [this](PoseStamped_&& s) { in_.push(in_.poses, std::move(s), Inbox::kMaxFrameInfo); });
    sim_status_in_ = std::make_unique<cell_dds::Reader<cell_msgs::msg::dds_::SimStatus_PubSubType>>(
        p, topic(cell_dds::kSimStatusTopic), cell_dds::reader_qos(Stream::kFrame),
        [this](SimStatus_&& s) { in_.push(in_.sim_statuses, std::move(s), Inbox::kMaxFrameInfo); });
    control_in_ = std::make_unique<cell_dds::Reader<cell_msgs::msg::dds_::SimControl_PubSubType>>(
        p, topic(o.commands == CommandSource::kSimulator ? cell_dds::kAcceptedTopic : cell_dds::kControlTopic),
        cell_dds::reader_qos(Stream::kCommand),
        [this](SimControl_&& c) { in_.push(in_.commands, std::move(c), Inbox::kMaxCommands); });
    std::vector<eprosima::fastrtps::rtps::GUID_t> readers{image_in_->guid(), info_in_->guid(), pose_in_->guid(),
                                                          sim_status_in_->guid(), control_in_->guid()};
    if (o.config.white_frame) {
      white_in_ = std::make_unique<cell_dds::Reader<sensor_msgs::msg::dds_::Image_PubSubType>>(
          p, topic(cell_dds::kWhiteImageTopic), cell_dds::reader_qos(Stream::kFrame), [this](Image_&& i) {
            {
              std::lock_guard<std::mutex> l(in_.m);
              in_.white_seen = true;
            }
            in_.push(in_.whites, std::move(i), Inbox::kMaxWhites);
          });
      readers.push_back(white_in_->guid());
    }
    node_ = std::make_unique<cell_dds::NodeAnnouncement>(
        p, "servo", readers,
        std::vector<eprosima::fastrtps::rtps::GUID_t>{twist_->guid(), spots_->guid(), status_->guid()}, o.ns.empty() ? std::string("/") : "/" + o.ns);
  }

  int run() {
    std::printf("servo: ready (pattern %s, model %s, domain %d)\n", o_.pattern.filename().c_str(),
                control::to_string(o_.config.law.model).c_str(), o_.domain_id);
    std::fflush(stdout);
    publish(machine_->ready(), false);
    const Clock::time_point t0 = Clock::now();
    const auto now = [&] { return std::chrono::duration<double>(Clock::now() - t0).count(); };
    std::unique_lock<std::mutex> lock(in_.m);
    while (!g_stop) {
      take_frame_info();
      while (!in_.commands.empty()) {
        machine_->on_command(in_.commands.front().command());
        in_.commands.pop_front();
      }
      if (in_.info_fresh) {
        in_.info_fresh = false;
        const std::string why = machine_->on_camera_info(to_info(*in_.info));
        if (!why.empty()) {
          std::fprintf(stderr, "servo: %s: %s\n", topic(cell_dds::kCameraInfoTopic).c_str(), why.c_str());
        }
      }
      if (in_.images.empty()) {
        in_.cv.wait_for(lock, std::chrono::milliseconds(5));
        if (auto lost = machine_->tick(now())) {
          lock.unlock();
          std::fprintf(stderr, "servo: LOST: %s, zero twist published\n", lost->reason.c_str());
          publish(*lost, false);
          lock.lock();
        }
        continue;
      }
      Image_ img = std::move(in_.images.front());
      in_.images.pop_front();
      const std::optional<Image_> white = wait_for_frame(to_stamp(img.header().stamp()), lock);
      const bool no_white_yet = white_in_ && !in_.white_seen;
      lock.unlock();
      if (no_white_yet && !said_no_white_) {  // said once: every image is rejected until one comes
        said_no_white_ = true;
        std::fprintf(stderr, "servo: %s: no white reference frame has come (--white-frame): images are rejected "
                     "until they come with theirs (cellsim serve --white-frame)\n",
                     topic(cell_dds::kWhiteImageTopic).c_str());
      }
      const ImageView white_view = white ? image_view(*white) : ImageView{};
      const ServoReply r = machine_->on_image(image_view(img), now(), white ? &white_view : nullptr);
      if (!r.notice.empty()) std::fprintf(stderr, "servo: %s\n", r.notice.c_str());
      if (r.taught && !o_.reference.empty()) {
        // a refused file (a user's, a link) is said, and the servo runs on: the reference it
        // taught is in memory, and a stop here would leave the robot without its last twist
        try {
          save_reference(o_.reference, machine_->pipeline().reference());
        } catch (const common::FileError& e) {
          std::fprintf(stderr, "servo: --reference %s; the taught reference is kept in memory only\n", e.what());
        }
      }
      if (r.answer) publish(r, true);
      lock.lock();
    }
    lock.unlock();
    // a clean exit leaves the robot still, and says so before the writers go
    publish(machine_->shutdown(), false);
    twist_->flush(std::chrono::milliseconds(500));
    status_->flush(std::chrono::milliseconds(500));
    std::printf("servo: stopped after %ld images (%ld rejected)\n", machine_->images(), machine_->rejected());
    return 0;
  }

 private:
  // The sim's status and pose for this frame, and its white frame, are sent before the image, on
  // other topics: they are given a moment to land (bounded: 100 ms; a white frame, once any has
  // come, up to kWhiteWaitMs, less than lockstep's republishing). Returns the white frame of
  // `stamp`, when the servo takes one and it came. Called with the lock held.
  std::optional<Image_> wait_for_frame(const Stamp& stamp, std::unique_lock<std::mutex>& lock) {
    const auto white_of_stamp = [&] {
      return std::find_if(in_.whites.begin(), in_.whites.end(),
                          [&](const Image_& w) { return to_stamp(w.header().stamp()) == stamp; });
    };
    for (int i = 0; i < 20 && !g_stop; ++i) {
      take_frame_info();
      if (machine_->frame_info_complete(stamp) && (!white_in_ || white_of_stamp() != in_.whites.end())) break;
      in_.cv.wait_for(lock, std::chrono::milliseconds(5));
    }
    take_frame_info();
    if (!white_in_) return std::nullopt;
    const auto deadline = Clock::now() + std::chrono::milliseconds(kWhiteWaitMs);
    while (in_.white_seen && white_of_stamp() == in_.whites.end() && !g_stop && Clock::now() < deadline)
      in_.cv.wait_until(lock, deadline);
    const auto it = white_of_stamp();
    if (it == in_.whites.end()) return std::nullopt;
    Image_ white = std::move(*it);
    in_.whites.erase(in_.whites.begin(), it + 1);  // and those of frames before it
    return white;
  }
  static constexpr int kWhiteWaitMs = 500;
  bool said_no_white_ = false;

  // called with the lock held
  void take_frame_info() {
    for (const auto& s : in_.sim_statuses)
      if (const auto f = frame_status(s)) machine_->on_sim_status(*f);
    in_.sim_statuses.clear();
    for (const auto& p : in_.poses)
      if (const auto T = camera_pose(p)) machine_->on_pose(to_stamp(p.header().stamp()), *T);
    in_.poses.clear();
  }

  // Publishes a reply: status before the twist (the sim reads both for the frame).
  void publish(const ServoReply& r, bool with_spots) {
    if (with_spots && r.spots) {
      auto m = spots_message(r);
      spots_->write(m);
    }
    auto s = status_message(r);
    status_->write(s);
    auto t = twist_message(r);
    twist_->write(t);
  }

  std::string topic(const char* t) const { return cell_dds::namespaced(o_.ns, t); }
  ServiceOptions o_;
  std::unique_ptr<ServoStateMachine> machine_;
  Inbox in_;
  cell_dds::ParticipantPtr participant_;
  std::unique_ptr<cell_dds::Writer<geometry_msgs::msg::dds_::TwistStamped_PubSubType>> twist_;
  std::unique_ptr<cell_dds::Writer<cell_msgs::msg::dds_::DecodedSpots_PubSubType>> spots_;
  std::unique_ptr<cell_dds::Writer<cell_msgs::msg::dds_::ServoStatus_PubSubType>> status_;
  std::unique_ptr<cell_dds::Reader<sensor_msgs::msg::dds_::Image_PubSubType>> image_in_;
  std::unique_ptr<cell_dds::Reader<sensor_msgs::msg::dds_::Image_PubSubType>> white_in_;  // --white-frame
  std::unique_ptr<cell_dds::Reader<sensor_msgs::msg::dds_::CameraInfo_PubSubType>> info_in_;
  std::unique_ptr<cell_dds::Reader<geometry_msgs::msg::dds_::PoseStamped_PubSubType>> pose_in_;
  std::unique_ptr<cell_dds::Reader<cell_msgs::msg::dds_::SimStatus_PubSubType>> sim_status_in_;
  std::unique_ptr<cell_dds::Reader<cell_msgs::msg::dds_::SimControl_PubSubType>> control_in_;
  std::unique_ptr<cell_dds::NodeAnnouncement> node_;
};

}  // namespace

std::unique_ptr<ServoPipeline> make_pipeline(const std::filesystem::path& pattern_file, const ServoConfig& config,
                                             const std::filesystem::path& reference) {
  const pattern::MArray marray = load_decodable_pattern(pattern_file);
  if (config.projector) check_projector_against_pattern(*config.projector, marray, pattern_file);
  auto pipeline = std::make_unique<ServoPipeline>(pattern::WindowTable(marray, {3, 3}), config);
  if (!reference.empty()) pipeline->set_reference(load_reference(reference));
  return pipeline;
}

pattern::MArray load_decodable_pattern(const std::filesystem::path& file) {
  const pattern::MArray marray = pattern::load_pattern(file, {3, 3});
  if (marray.colours > kDecodableColours)
    throw std::runtime_error(file.string() + ": the pattern has " + std::to_string(marray.colours) +
                             " colours; the decoder tells apart " + std::to_string(kDecodableColours) +
                             " (the projector's primaries: blue, green, red)");
  return marray;
}

void load_servo_config(const std::filesystem::path& file, ServoConfig& c) {
  using common::Reader;
  try {
    const Reader top(file, common::load_yaml_file(file, "servo configuration"));
    top.only_keys({"model", "z_hat_m", "gain", "gain_adaptive", "max_linear_mps", "max_angular_dps", "min_points",
                   "converge_mm", "converge_deg", "min_votes", "min_island", "tolerant", "epipolar_px",
                   "segment_length", "propagate_sources", "points", "interior_points", "divergence_ratio", "robust",
                   "visual_features", "crosstalk", "fitted_lines", "taught_points", "white_frame"});
    constexpr double kDeg = 3.14159265358979323846 / 180;
    if (top.has("model")) {
      const Reader m = top.at("model");
      try {
        c.law.model = control::parse_interaction_model(m.text(64));
      } catch (const std::exception& e) {
        m.fail(std::string("must be desired-constant-depth, desired, current or mean, got ") + m.spelling());
      }
    }
    if (top.has("z_hat_m")) c.law.z_hat_m = top.at("z_hat_m").in_range(1e-3, 100);
    if (top.has("gain") && top.has("gain_adaptive")) top.fail("give gain or gain_adaptive, not both");
    if (top.has("gain")) {
      const double g = top.at("gain").in_range(1e-6, 100);
      c.law.gain = {g, g, 0};
    }
    if (top.has("gain_adaptive")) {
      const Reader g = top.at("gain_adaptive");
      if (g.size() != 3) g.fail("must be [l0, linf, slope]: gain at zero error, gain at large error, slope");
      c.law.gain = {g.at(std::size_t{0}).in_range(1e-6, 100), g.at(std::size_t{1}).in_range(1e-6, 100),
                    g.at(std::size_t{2}).in_range(0, 1e6)};
    }
    if (top.has("max_linear_mps")) c.law.max_linear_mps = top.at("max_linear_mps").in_range(1e-6, 10);
    if (top.has("max_angular_dps")) c.law.max_angular_radps = top.at("max_angular_dps").in_range(1e-6, 3600) * kDeg;
    if (top.has("min_points")) c.law.min_points = top.at("min_points").integer_in(3, 4096);
    if (top.has("converge_mm")) c.law.convergence_translation_m = top.at("converge_mm").in_range(1e-6, 1000) / 1e3;
    if (top.has("converge_deg")) c.law.convergence_rotation_rad = top.at("converge_deg").in_range(1e-6, 180) * kDeg;
    if (top.has("min_votes")) c.decoder.min_votes = top.at("min_votes").integer_in(1, 9);
    if (top.has("min_island")) c.decoder.min_island = top.at("min_island").integer_in(0, 4096);
    if (top.has("tolerant")) c.decoder.tolerance.enabled = top.at("tolerant").boolean();
    // with a projector calibration (--projector): the epipolar steps (docs/decoding.md)
    if (top.has("epipolar_px")) c.decoder.epipolar.tolerance_px = top.at("epipolar_px").in_range(0.01, 100);
    if (top.has("segment_length")) c.decoder.epipolar.segment_length = top.at("segment_length").integer_in(0, 15);
    // the camera's colour crosstalk, as calibrated (vision::SegmentationOptions::crosstalk)
    if (top.has("crosstalk")) c.decoder.segmentation.crosstalk = top.at("crosstalk").in_range(0, vision::kMaxCrosstalk);
    if (top.has("points")) c.points = top.at("points").integer_in(0, 4096);
    if (top.has("interior_points")) c.interior_points = top.at("interior_points").boolean();
    // with a projector calibration: each id held to the point its spot lit at teaching
    if (top.has("taught_points")) c.taught_points = top.at("taught_points").boolean();
    // each image with the white reference frame of its stamp (rt/camera/white/image_raw)
    if (top.has("white_frame")) c.white_frame = top.at("white_frame").boolean();
    // without a projector calibration: decode again on each frame's fitted lines
    if (top.has("fitted_lines")) c.decoder.epipolar.fitted_lines = top.at("fitted_lines").boolean();
    if (top.has("divergence_ratio")) c.divergence_ratio = top.at("divergence_ratio").in_range(0, 1e6);
    if (top.has("robust")) {
      const Reader r = top.at("robust");
      try {
        c.law.robust = control::parse_robust_estimator(r.text(16));
      } catch (const std::invalid_argument&) {
        r.fail("must be tukey, huber or none, got " + r.spelling());
      }
    }
    if (top.has("visual_features")) {
      const Reader r = top.at("visual_features");
      try {
        c.law.features = control::parse_visual_features(r.text(16));
      } catch (const std::invalid_argument&) {
        r.fail("must be points, moments, surface or plane, got " + r.spelling());
      }
    }
    if (top.has("propagate_sources")) c.decoder.epipolar.min_sources = top.at("propagate_sources").integer_in(1, 9);
  } catch (const common::ConfigError& e) {
    throw std::runtime_error(e.what());
  }
}

int run_servo_service(const ServiceOptions& options) {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::signal(SIGHUP, on_signal);  // a closed terminal or ssh session: stop as cleanly as on Ctrl-C
  ServoService s(options);
  return s.run();
}

}  // namespace servo
