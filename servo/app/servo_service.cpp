#include "servo/app/servo_service.hpp"

#include <yaml-cpp/yaml.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <deque>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>

#include "cell_msgsPubSubTypes.h"
#include "dds/endpoint.hpp"
#include "dds/topics.hpp"
#include "geometry_msgsPubSubTypes.h"
#include "sensor_msgsPubSubTypes.h"
#include "servo/pattern/pattern_file.hpp"

namespace servo {
namespace {

using Clock = std::chrono::steady_clock;
using sensor_msgs::msg::dds_::Image_;
using sensor_msgs::msg::dds_::CameraInfo_;
using geometry_msgs::msg::dds_::PoseStamped_;
using cell_msgs::msg::dds_::SimControl_;
namespace SS = cell_msgs::msg::dds_::ServoStatus_Constants;
namespace SC = cell_msgs::msg::dds_::SimControl_Constants;

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

void save_reference(const std::filesystem::path& file, const std::vector<control::Feature>& s) {
  nlohmann::json j = nlohmann::json::array();
  for (const auto& f : s) {
    nlohmann::json e{{"row", f.row}, {"col", f.col}, {"x", f.x}, {"y", f.y}};
    e["z"] = f.z ? nlohmann::json(*f.z) : nlohmann::json(nullptr);
    j.push_back(e);
  }
  std::ofstream(file) << j.dump(1) << "\n";
}

std::vector<control::Feature> load_reference(const std::filesystem::path& file) {
  std::ifstream in(file);
  nlohmann::json j;
  try {
    in >> j;
  } catch (const std::exception& e) {
    throw std::runtime_error(file.string() + ": not a reference file (JSON list of features): " + e.what());
  }
  std::vector<control::Feature> out;
  for (const auto& e : j) {
    control::Feature f{e.at("row").get<int>(), e.at("col").get<int>(), e.at("x").get<double>(), e.at("y").get<double>(),
                       std::nullopt};
    if (!e.at("z").is_null()) f.z = e.at("z").get<double>();
    if (!std::isfinite(f.x) || !std::isfinite(f.y)) throw std::runtime_error(file.string() + ": non-finite feature");
    out.push_back(f);
  }
  return out;
}

struct Inbox {
  std::mutex m;
  std::condition_variable cv;
  std::deque<Image_> images;
  std::deque<PoseStamped_> poses;
  std::deque<SimControl_> commands;
  std::optional<CameraInfo_> info;
};

class ServoService {
 public:
  explicit ServoService(const ServiceOptions& o) : o_(o) {
    const pattern::MArray marray = pattern::load_pattern(o.pattern, {3, 3});
    pipeline_ = std::make_unique<ServoPipeline>(pattern::WindowTable(marray, {3, 3}), o.config);
    if (!o.reference.empty() && std::filesystem::exists(o.reference)) {
      pipeline_->set_reference(load_reference(o.reference));
      std::printf("servo: reference loaded from %s (%zu features)\n", o.reference.c_str(), pipeline_->reference().size());
    }
    cell_dds::ParticipantOptions po;
    po.domain_id = o.domain_id;
    po.name = "servo";
    participant_ = cell_dds::make_participant(po);
    auto& p = *participant_;
    using cell_dds::Stream;
    twist_ = std::make_unique<cell_dds::Writer<geometry_msgs::msg::dds_::TwistStamped_PubSubType>>(
        p, cell_dds::kTwistTopic, cell_dds::writer_qos(Stream::kFrame));
    spots_ = std::make_unique<cell_dds::Writer<cell_msgs::msg::dds_::DecodedSpots_PubSubType>>(
        p, cell_dds::kSpotsTopic, cell_dds::writer_qos(Stream::kFrame));
    status_ = std::make_unique<cell_dds::Writer<cell_msgs::msg::dds_::ServoStatus_PubSubType>>(
        p, cell_dds::kStatusTopic, cell_dds::writer_qos(Stream::kLatched));
    image_in_ = std::make_unique<cell_dds::Reader<sensor_msgs::msg::dds_::Image_PubSubType>>(
        p, cell_dds::kImageTopic, cell_dds::reader_qos(Stream::kFrame), [this](Image_&& i) {
          std::lock_guard<std::mutex> l(in_.m);
          in_.images.push_back(std::move(i));
          if (in_.images.size() > 2) in_.images.pop_front();  // realtime: never queue stale frames
          in_.cv.notify_all();
        });
    info_in_ = std::make_unique<cell_dds::Reader<sensor_msgs::msg::dds_::CameraInfo_PubSubType>>(
        p, cell_dds::kCameraInfoTopic, cell_dds::reader_qos(Stream::kLatched), [this](CameraInfo_&& c) {
          std::lock_guard<std::mutex> l(in_.m);
          in_.info = std::move(c);
        });
    pose_in_ = std::make_unique<cell_dds::Reader<geometry_msgs::msg::dds_::PoseStamped_PubSubType>>(
        p, cell_dds::kCameraPoseTopic, cell_dds::reader_qos(Stream::kFrame), [this](PoseStamped_&& s) {
          std::lock_guard<std::mutex> l(in_.m);
          in_.poses.push_back(std::move(s));
          if (in_.poses.size() > 8) in_.poses.pop_front();
          in_.cv.notify_all();
        });
    control_in_ = std::make_unique<cell_dds::Reader<cell_msgs::msg::dds_::SimControl_PubSubType>>(
        p, cell_dds::kControlTopic, cell_dds::reader_qos(Stream::kCommand), [this](SimControl_&& c) {
          std::lock_guard<std::mutex> l(in_.m);
          in_.commands.push_back(std::move(c));
          in_.cv.notify_all();
        });
    state_ = pipeline_->taught() && o.autostart ? SS::SERVOING : SS::IDLE;
  }

  int run() {
    std::printf("servo: ready (pattern %s, model %s, domain %d)\n", o_.pattern.filename().c_str(),
                control::to_string(o_.config.law.model).c_str(), o_.domain_id);
    std::fflush(stdout);
    publish_status(builtin_interfaces::msg::dds_::Time_(), "ready");
    auto last_image = Clock::now();
    bool lost_reported = false;
    std::unique_lock<std::mutex> lock(in_.m);
    while (!g_stop) {
      while (!in_.commands.empty()) {
        const SimControl_ c = std::move(in_.commands.front());
        in_.commands.pop_front();
        command(c);
      }
      if (in_.images.empty()) {
        in_.cv.wait_for(lock, std::chrono::milliseconds(20));
        // no image for lost_ms: stop the robot and say so (once per outage)
        if (Clock::now() - last_image > std::chrono::duration<double, std::milli>(o_.lost_ms) && !lost_reported &&
            images_seen_ > 0) {
          lost_reported = true;
          previous_state_ = state_;
          state_ = SS::LOST;
          lock.unlock();
          publish_twist(last_stamp_, control::Vector6d::Zero());
          publish_status(last_stamp_, "no image for " + std::to_string(static_cast<int>(o_.lost_ms)) + " ms");
          std::fprintf(stderr, "servo: LOST: no image for %.0f ms, zero twist published\n", o_.lost_ms);
          lock.lock();
        }
        continue;
      }
      Image_ img = std::move(in_.images.front());
      in_.images.pop_front();
      last_image = Clock::now();
      if (lost_reported) {
        lost_reported = false;
        state_ = previous_state_;
      }
      ++images_seen_;
      // the pose of this frame, when the sim sends one (it is sent before the image)
      std::optional<Eigen::Isometry3d> pose = pose_for(img.header().stamp(), lock);
      std::optional<CameraInfo_> info = in_.info;
      lock.unlock();
      process(img, info, pose);
      lock.lock();
    }
    lock.unlock();
    // a clean exit leaves the robot still
    publish_twist(last_stamp_, control::Vector6d::Zero());
    state_ = SS::STOPPED;
    publish_status(last_stamp_, "servo shut down");
    std::printf("servo: stopped after %ld images\n", images_seen_);
    return 0;
  }

 private:
  std::optional<Eigen::Isometry3d> pose_for(const builtin_interfaces::msg::dds_::Time_& stamp,
                                            std::unique_lock<std::mutex>& lock) {
    for (int attempt = 0; attempt < 20; ++attempt) {
      for (const auto& p : in_.poses)
        if (p.header().stamp() == stamp) {
          Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
          T.translation() = Eigen::Vector3d(p.pose().position().x(), p.pose().position().y(), p.pose().position().z());
          T.linear() = Eigen::Quaterniond(p.pose().orientation().w(), p.pose().orientation().x(),
                                          p.pose().orientation().y(), p.pose().orientation().z())
                           .normalized()
                           .toRotationMatrix();
          return T;
        }
      if (in_.poses.empty() && attempt > 0) return std::nullopt;  // no pose source at all
      in_.cv.wait_for(lock, std::chrono::milliseconds(5));
    }
    return std::nullopt;
  }

  void command(const SimControl_& c) {
    switch (c.command()) {
      case SC::TEACH: state_ = SS::TEACHING; break;
      case SC::START:
        // commands can arrive before the teach image: START then takes effect once taught
        started_ = true;
        if (pipeline_->taught() && state_ != SS::TEACHING) state_ = SS::SERVOING;
        break;
      case SC::PAUSE:
        started_ = false;
        state_ = SS::STOPPED;
        break;
      case SC::RESET:
      case SC::LOAD_SCENARIO:
        if (state_ != SS::TEACHING) state_ = SS::IDLE;
        break;
      default: break;
    }
  }

  // Checks an image before decoding; returns the reason it is unusable, or empty.
  static std::string reject_reason(const Image_& img, const std::optional<CameraInfo_>& info) {
    if (img.encoding() != "rgb8") return "rejected image: encoding '" + img.encoding() + "', expected rgb8";
    if (img.width() == 0 || img.height() == 0) return "rejected image: empty";
    if (img.step() != img.width() * 3) return "rejected image: step " + std::to_string(img.step()) + " for width " + std::to_string(img.width());
    if (img.data().size() != static_cast<std::size_t>(img.step()) * img.height())
      return "rejected image: " + std::to_string(img.data().size()) + " bytes for " + std::to_string(img.width()) + " x " +
             std::to_string(img.height());
    if (!info) return "waiting for camera_info";
    if (info->width() != img.width() || info->height() != img.height())
      return "rejected image: " + std::to_string(img.width()) + " x " + std::to_string(img.height()) +
             ", camera_info says " + std::to_string(info->width()) + " x " + std::to_string(info->height());
    return "";
  }

  void process(const Image_& img, const std::optional<CameraInfo_>& info, const std::optional<Eigen::Isometry3d>& pose) {
    const auto& stamp = img.header().stamp();
    last_stamp_ = stamp;
    const std::string bad = reject_reason(img, info);
    if (!bad.empty()) {
      ++rejected_;
      publish_twist(stamp, control::Vector6d::Zero());
      publish_status(stamp, bad);
      return;
    }
    control::CameraIntrinsics& cam = pipeline_->config().camera;
    cam.fx = info->k()[0];
    cam.cx = info->k()[2];
    cam.fy = info->k()[4];
    cam.cy = info->k()[5];
    for (std::size_t i = 0; i < 5; ++i) cam.distortion[i] = i < info->d().size() ? info->d()[i] : 0.0;

    const cv::Mat rgb(static_cast<int>(img.height()), static_cast<int>(img.width()), CV_8UC3,
                      const_cast<uint8_t*>(img.data().data()), img.step());
    int detected = 0;
    std::vector<ImageSpot> spots;
    try {
      spots = pipeline_->locate(rgb, &detected);
    } catch (const std::exception& e) {
      publish_twist(stamp, control::Vector6d::Zero());
      publish_status(stamp, std::string("rejected image: ") + e.what());
      return;
    }
    publish_spots(stamp, spots, detected);
    decoded_ = static_cast<int>(spots.size());
    if (state_ == SS::TEACHING) {
      const int n = pipeline_->teach(spots, pose);
      if (!o_.reference.empty()) save_reference(o_.reference, pipeline_->reference());
      state_ = o_.autostart || started_ ? SS::SERVOING : SS::IDLE;
      matched_ = n;
      publish_twist(stamp, control::Vector6d::Zero());
      publish_status(stamp, "taught " + std::to_string(n) + " features");
      return;
    }
    if (state_ != SS::SERVOING && state_ != SS::CONVERGED) {
      publish_twist(stamp, control::Vector6d::Zero());
      publish_status(stamp, pipeline_->taught() ? "waiting for START" : "no reference: send TEACH");
      return;
    }
    StepResult step;
    try {
      step = pipeline_->step(spots, pose);
    } catch (const std::exception& e) {
      publish_twist(stamp, control::Vector6d::Zero());
      publish_status(stamp, e.what());
      return;
    }
    ++iteration_;
    error_norm_ = step.control.error_norm;
    matched_ = static_cast<int>(step.matched.size());
    std::string reason;
    switch (step.control.status) {
      case control::ControlStatus::kServoing: state_ = SS::SERVOING; break;
      case control::ControlStatus::kConverged: state_ = SS::CONVERGED; reason = step.control.reason; break;
      default: state_ = SS::SERVOING; reason = "safe stop: " + step.control.reason; break;  // zero twist, keep trying
    }
    publish_status(stamp, reason);  // before the twist: the sim reads both for this frame
    publish_twist(stamp, step.control.twist);
  }

  void publish_twist(const builtin_interfaces::msg::dds_::Time_& stamp, const control::Vector6d& v) {
    geometry_msgs::msg::dds_::TwistStamped_ t;
    t.header().stamp(stamp);
    t.header().frame_id(cell_dds::kCameraFrame);
    t.twist().linear().x(v[0]);
    t.twist().linear().y(v[1]);
    t.twist().linear().z(v[2]);
    t.twist().angular().x(v[3]);
    t.twist().angular().y(v[4]);
    t.twist().angular().z(v[5]);
    twist_->write(t);
  }

  void publish_status(const builtin_interfaces::msg::dds_::Time_& stamp, const std::string& reason) {
    cell_msgs::msg::dds_::ServoStatus_ s;
    s.header().stamp(stamp);
    s.header().frame_id(cell_dds::kCameraFrame);
    s.state(state_);
    s.iteration(static_cast<uint32_t>(iteration_));
    s.error_norm(error_norm_);
    s.decoded(static_cast<uint32_t>(decoded_));
    s.matched(static_cast<uint32_t>(matched_));
    s.reason(reason);
    status_->write(s);
  }

  void publish_spots(const builtin_interfaces::msg::dds_::Time_& stamp, const std::vector<ImageSpot>& spots, int detected) {
    cell_msgs::msg::dds_::DecodedSpots_ m;
    m.header().stamp(stamp);
    m.header().frame_id(cell_dds::kCameraFrame);
    m.detected(static_cast<uint32_t>(detected));
    for (const auto& s : spots) {
      cell_msgs::msg::dds_::Spot_ x;
      x.row(static_cast<int16_t>(s.row));
      x.col(static_cast<int16_t>(s.col));
      x.u(s.u);
      x.v(s.v);
      m.spots().push_back(x);
    }
    spots_->write(m);
  }

  ServiceOptions o_;
  std::unique_ptr<ServoPipeline> pipeline_;
  Inbox in_;
  uint8_t state_ = SS::IDLE, previous_state_ = SS::IDLE;
  bool started_ = false;
  long images_seen_ = 0, rejected_ = 0;
  long iteration_ = 0;
  double error_norm_ = 0;
  int decoded_ = 0, matched_ = 0;
  builtin_interfaces::msg::dds_::Time_ last_stamp_;
  cell_dds::ParticipantPtr participant_;
  std::unique_ptr<cell_dds::Writer<geometry_msgs::msg::dds_::TwistStamped_PubSubType>> twist_;
  std::unique_ptr<cell_dds::Writer<cell_msgs::msg::dds_::DecodedSpots_PubSubType>> spots_;
  std::unique_ptr<cell_dds::Writer<cell_msgs::msg::dds_::ServoStatus_PubSubType>> status_;
  std::unique_ptr<cell_dds::Reader<sensor_msgs::msg::dds_::Image_PubSubType>> image_in_;
  std::unique_ptr<cell_dds::Reader<sensor_msgs::msg::dds_::CameraInfo_PubSubType>> info_in_;
  std::unique_ptr<cell_dds::Reader<geometry_msgs::msg::dds_::PoseStamped_PubSubType>> pose_in_;
  std::unique_ptr<cell_dds::Reader<cell_msgs::msg::dds_::SimControl_PubSubType>> control_in_;
};

}  // namespace

void load_servo_config(const std::filesystem::path& file, ServoConfig& c) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(file.string());
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(file.string() + ": " + e.what());
  }
  static const std::set<std::string> keys{"model", "z_hat_m", "gain", "gain_adaptive", "max_linear_mps", "max_angular_dps",
                                          "min_points", "converge_mm", "converge_deg", "min_votes", "min_island", "tolerant"};
  if (!root.IsMap()) throw std::runtime_error(file.string() + ": must be a mapping of settings");
  for (const auto& kv : root) {
    const std::string key = kv.first.as<std::string>();
    if (!keys.count(key)) throw std::runtime_error(file.string() + ": " + key + ": unknown key");
    const auto num = [&](double lo) {
      double v;
      try {
        v = kv.second.as<double>();
      } catch (const YAML::Exception&) {
        throw std::runtime_error(file.string() + ": " + key + ": must be a number");
      }
      if (!std::isfinite(v) || v < lo) throw std::runtime_error(file.string() + ": " + key + ": out of range");
      return v;
    };
    if (key == "model") c.law.model = control::parse_interaction_model(kv.second.as<std::string>());
    else if (key == "z_hat_m") c.law.z_hat_m = num(1e-3);
    else if (key == "gain") c.law.gain = {num(1e-6), num(1e-6), 0};
    else if (key == "gain_adaptive") {
      if (!kv.second.IsSequence() || kv.second.size() != 3) throw std::runtime_error(file.string() + ": gain_adaptive: [l0, linf, slope]");
      c.law.gain = {kv.second[0].as<double>(), kv.second[1].as<double>(), kv.second[2].as<double>()};
    } else if (key == "max_linear_mps") c.law.max_linear_mps = num(1e-6);
    else if (key == "max_angular_dps") c.law.max_angular_radps = num(1e-6) * 3.14159265358979323846 / 180;
    else if (key == "min_points") c.law.min_points = static_cast<int>(num(3));
    else if (key == "converge_mm") c.law.convergence_translation_m = num(1e-9) / 1e3;
    else if (key == "converge_deg") c.law.convergence_rotation_rad = num(1e-9) * 3.14159265358979323846 / 180;
    else if (key == "min_votes") c.decoder.min_votes = static_cast<int>(num(1));
    else if (key == "min_island") c.decoder.min_island = static_cast<int>(num(0));
    else if (key == "tolerant") c.decoder.tolerance.enabled = kv.second.as<bool>();
  }
}

control::ProjectorModel load_projector_calibration(const std::filesystem::path& file) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(file.string());
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(file.string() + ": " + e.what());
  }
  static const std::set<std::string> keys{"fx", "fy", "cx", "cy", "spot_pitch_px", "rows", "cols", "position_m",
                                          "orientation_xyzw"};
  if (!root.IsMap()) throw std::runtime_error(file.string() + ": must be a mapping");
  for (const auto& kv : root)
    if (!keys.count(kv.first.as<std::string>()))
      throw std::runtime_error(file.string() + ": " + kv.first.as<std::string>() + ": unknown key");
  const auto num = [&](const char* key, double lo) {
    if (!root[key]) throw std::runtime_error(file.string() + ": " + key + ": missing");
    double v;
    try {
      v = root[key].as<double>();
    } catch (const YAML::Exception&) {
      throw std::runtime_error(file.string() + ": " + key + ": must be a number");
    }
    if (!std::isfinite(v) || v < lo) throw std::runtime_error(file.string() + ": " + key + ": out of range");
    return v;
  };
  const auto list = [&](const char* key, std::size_t n) {
    if (!root[key] || !root[key].IsSequence() || root[key].size() != n)
      throw std::runtime_error(file.string() + ": " + key + ": must be a list of " + std::to_string(n) + " numbers");
    std::vector<double> v;
    for (const auto& x : root[key]) v.push_back(x.as<double>());
    for (double x : v)
      if (!std::isfinite(x)) throw std::runtime_error(file.string() + ": " + key + ": not finite");
    return v;
  };
  control::ProjectorModel m;
  m.fx = num("fx", 1e-6);
  m.fy = num("fy", 1e-6);
  m.cx = num("cx", -1e9);
  m.cy = num("cy", -1e9);
  m.spot_pitch_px = num("spot_pitch_px", 1e-6);
  m.rows = static_cast<int>(num("rows", 3));
  m.cols = static_cast<int>(num("cols", 3));
  const auto p = list("position_m", 3);
  const auto q = list("orientation_xyzw", 4);
  m.world_T_projector = Eigen::Isometry3d::Identity();
  m.world_T_projector.translation() = Eigen::Vector3d(p[0], p[1], p[2]);
  m.world_T_projector.linear() = Eigen::Quaterniond(q[3], q[0], q[1], q[2]).normalized().toRotationMatrix();
  return m;
}

int run_servo_service(const ServiceOptions& options) {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  ServoService s(options);
  return s.run();
}

}  // namespace servo
