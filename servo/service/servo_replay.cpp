#include "servo/service/servo_replay.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <iomanip>
#include <map>
#include <string>
#include <vector>

#include "cell_msgsPubSubTypes.h"
#include "common/output_file.hpp"
#include "common/strict_yaml.hpp"
#include "dds/topics.hpp"
#include "geometry_msgsPubSubTypes.h"
#include "mcap/mcap_reader.hpp"
#include "record/recorder.hpp"
#include "sensor_msgsPubSubTypes.h"
#include "servo/messages/servo_messages.hpp"
#include "servo/service/servo_service.hpp"

namespace servo {
namespace {

// One twist, recorded or replayed, with the servo's words on it.
struct TwistAt {
  Stamp stamp;
  control::Vector6d twist = control::Vector6d::Zero();
  int state = 0;
  double error_norm = 0;
  std::uint32_t decoded = 0;
};

double seconds(const Stamp& s) { return s.sec + s.nanosec * 1e-9; }
bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// the cell's topic in a recording, under any namespace ("/cell2/camera/image_raw")
bool is_topic(const std::string& recorded, const char* dds_topic) {
  const std::string t = cell_record::ros_topic_name(dds_topic);
  return recorded.size() >= t.size() && recorded.compare(recorded.size() - t.size(), t.size(), t) == 0 &&
         (recorded.size() == t.size() || recorded[recorded.size() - t.size()] == '/');
}

template <typename PubSubType>
typename PubSubType::type decode(const mcap::Channel& c, const mcap::MessageView& m, const std::string& file) {
  PubSubType type;
  eprosima::fastrtps::rtps::SerializedPayload_t p(static_cast<std::uint32_t>(m.size));
  if (m.size > 0) std::memcpy(p.data, m.data, m.size);
  p.length = static_cast<std::uint32_t>(m.size);
  typename PubSubType::type out;
  bool ok = false;
  try {
    ok = type.deserialize(&p, &out);
  } catch (const std::exception&) {
    ok = false;
  }
  if (!ok)
    throw std::runtime_error(file + ": message " + std::to_string(m.sequence) + " on " + c.topic + " does not decode as " +
                             type.getName());
  return out;
}

// Replays a recording in the order it holds, or in the order its messages arrived (a bag
// `ros2 bag record` made of the live cell): the servo answers an image once its frame's sim
// status (and camera pose, when the recording has poses) are there, as it waits for them live.
// An image whose status never comes is answered when the next image or a command is heard.
class Replay {
 public:
  explicit Replay(const ReplayOptions& o) : o_(o) {
    machine_ = std::make_unique<ServoStateMachine>(make_pipeline(o.pattern, o.config, o.reference),
                                                   ServoTiming{o.lost_ms / 1e3, o.autostart});
    const ServoReply ready = machine_->ready();
    ready_ = TwistAt{ready.stamp, ready.twist, static_cast<int>(ready.state), 0, 0};
  }

  using Key = std::pair<std::int32_t, std::uint32_t>;
  static Key key(const Stamp& s) { return {s.sec, s.nanosec}; }

  void on_message(const mcap::Channel& c, const mcap::MessageView& m) {
    if (!t0_) t0_ = m.log_time_ns;
    const double now = static_cast<double>(m.log_time_ns - std::min(*t0_, m.log_time_ns)) * 1e-9;
    // a LOST notice comes from the servo's clock, not from an image: counted, not compared
    if (machine_->tick(now)) ++lost_replayed_;
    const std::string& file = o_.recording.string();
    if (is_topic(c.topic, cell_dds::kImageTopic)) {
      flush();  // the image before waits no longer: its frame is over
      auto img = decode<sensor_msgs::msg::dds_::Image_PubSubType>(c, m, file);
      ++images_;
      const Stamp at = to_stamp(img.header().stamp());
      if (!last_image_ || std::make_pair(at.sec, at.nanosec) > std::make_pair(last_image_->sec, last_image_->nanosec))
        last_image_ = at;
      pending_ = Pending{std::move(img), key(at), now};
      if (complete(pending_->key)) flush();
    } else if (is_topic(c.topic, cell_dds::kWhiteImageTopic)) {
      // a white reference frame, sent before the image of its stamp: kept for it (a few)
      white_recorded_ = true;
      if (!o_.config.white_frame) return;
      auto white = decode<sensor_msgs::msg::dds_::Image_PubSubType>(c, m, file);
      const Key k = key(to_stamp(white.header().stamp()));
      whites_.emplace_back(k, std::move(white));
      if (whites_.size() > kMaxWhites) whites_.pop_front();
      if (pending_ && complete(pending_->key)) flush();
    } else if (is_topic(c.topic, cell_dds::kCameraInfoTopic)) {
      const std::string why = machine_->on_camera_info(to_info(decode<sensor_msgs::msg::dds_::CameraInfo_PubSubType>(c, m, file)));
      if (!why.empty()) std::fprintf(stderr, "servo replay: %s: %s: %s\n", file.c_str(), c.topic.c_str(), why.c_str());
    } else if (is_topic(c.topic, cell_dds::kSimStatusTopic)) {
      const auto s = decode<cell_msgs::msg::dds_::SimStatus_PubSubType>(c, m, file);
      if (const auto f = frame_status(s)) {
        machine_->on_sim_status(*f);
        seen(statuses_, key(to_stamp(s.header().stamp())));
      }
    } else if (is_topic(c.topic, cell_dds::kCameraPoseTopic)) {
      const auto p = decode<geometry_msgs::msg::dds_::PoseStamped_PubSubType>(c, m, file);
      if (const auto T = camera_pose(p)) machine_->on_pose(to_stamp(p.header().stamp()), *T);
      poses_in_file_ = true;
      seen(poses_, key(to_stamp(p.header().stamp())));
    } else if (is_topic(c.topic, o_.commands == CommandSource::kSimulator ? cell_dds::kAcceptedTopic : cell_dds::kControlTopic)) {
      flush();  // a command heard after an image acts after it, as it did live
      machine_->on_command(decode<cell_msgs::msg::dds_::SimControl_PubSubType>(c, m, file).command());
    } else if (is_topic(c.topic, cell_dds::kStatusTopic)) {
      const auto st = decode<cell_msgs::msg::dds_::ServoStatus_PubSubType>(c, m, file);
      if (st.state() == cell_dds::to_wire(cell_dds::ServoState::kLost) && lost_recorded_at_.size() < kMaxLostStamps)
        ++lost_recorded_at_[key(to_stamp(st.header().stamp()))];
    } else if (is_topic(c.topic, cell_dds::kTwistTopic)) {
      const auto t = decode<geometry_msgs::msg::dds_::TwistStamped_PubSubType>(c, m, file);
      TwistAt r;
      r.stamp = to_stamp(t.header().stamp());
      const auto& l = t.twist().linear();
      const auto& a = t.twist().angular();
      r.twist << l.x(), l.y(), l.z(), a.x(), a.y(), a.z();
      recorded_.push_back(r);
    }
  }

  // `cut`: the recording ends before its footer, or says it stopped before the run ended (a
  // full disk, the size limit: kStoppedMetadata), and a twist recorded after the last image it
  // holds answered an image past the cut (the recorder writes the small twist as it comes and
  // the image's megabyte after it: the twist can land in the last complete chunk, the image in
  // the lost one): such twists are counted apart, not as unanswered
  long images() const { return images_; }
  bool white_recorded() const { return white_recorded_; }

  ReplayResult compare_and_write(bool cut) {
    flush();  // the last image, whatever came of its status
    ReplayResult res;
    res.images = images_;
    res.white_frames = white_recorded_;
    // replayed twists by stamp, in order (a republished frame is answered again)
    std::map<std::pair<std::int32_t, std::uint32_t>, std::deque<TwistAt>> by_stamp;
    for (const auto& r : replayed_) by_stamp[{r.stamp.sec, r.stamp.nanosec}].push_back(r);
    // The servo's "ready" twist is in the recording only when the recorder had matched the
    // servo's writer as it started, and it may be heard before or after the first frame
    // went out (the two processes race). So it is counted, not timed: the recording holds it
    // when it holds one twist more with the ready stamp than the replay answered frames with.
    auto& at_ready = by_stamp[{ready_.stamp.sec, ready_.stamp.nanosec}];
    const auto recorded_at_ready = std::count_if(recorded_.begin(), recorded_.end(), [&](const TwistAt& r) {
      return r.stamp.sec == ready_.stamp.sec && r.stamp.nanosec == ready_.stamp.nanosec;
    });
    if (recorded_at_ready > static_cast<long>(at_ready.size())) at_ready.push_front(ready_);
    common::OutputStream csv;
    if (!o_.output.empty()) {
      common::make_output_folder(o_.output);
      csv.open(o_.output / "replay.csv", "table");
      csv << "# servo replay of " << o_.recording.string() << ": each recorded twist and the one the replayed servo "
          << "sends for the same stamp\n"
          << "t,rec_vx,rec_vy,rec_vz,rec_wx,rec_wy,rec_wz,vx,vy,vz,wx,wy,wz,state,error_norm,decoded,max_abs_diff,"
             "identical\n"
          << std::setprecision(17);
    }
    res.lost_replayed = lost_replayed_;
    for (const auto& rec : recorded_) {
      auto it = by_stamp.find({rec.stamp.sec, rec.stamp.nanosec});
      if (it == by_stamp.end() || it->second.empty()) {
        // the live servo's LOST notice (its status at that stamp says LOST, its twist zero):
        // the live clock saw no image for a while, which a replay cannot time alike
        auto lost = lost_recorded_at_.find({rec.stamp.sec, rec.stamp.nanosec});
        if (lost != lost_recorded_at_.end() && lost->second > 0 && rec.twist.isZero(0)) {
          --lost->second;
          ++res.lost_recorded;
          continue;
        }
        const bool past_cut = cut && (!last_image_ || std::make_pair(rec.stamp.sec, rec.stamp.nanosec) >
                                                                 std::make_pair(last_image_->sec, last_image_->nanosec));
        ++(past_cut ? res.past_cut : res.recorded_only);
        continue;
      }
      const TwistAt rep = it->second.front();
      it->second.pop_front();
      ++res.compared;
      bool identical = true;
      double diff = 0;
      for (int k = 0; k < 6; ++k) {
        identical = identical && same_bits(rec.twist[k], rep.twist[k]);
        diff = std::max(diff, std::abs(rec.twist[k] - rep.twist[k]));
      }
      if (!identical) {
        ++res.differing;
        if (!res.first_differing_s) res.first_differing_s = seconds(rec.stamp);
      }
      res.max_difference = std::max(res.max_difference, diff);
      if (csv.is_open()) {
        csv << seconds(rec.stamp);
        for (int k = 0; k < 6; ++k) csv << ',' << rec.twist[k];
        for (int k = 0; k < 6; ++k) csv << ',' << rep.twist[k];
        csv << ',' << rep.state << ',' << rep.error_norm << ',' << rep.decoded << ',' << diff << ',' << (identical ? 1 : 0)
            << '\n';
      }
    }
    for (const auto& [stamp, left] : by_stamp) res.replayed_only += static_cast<long>(left.size());
    csv.close();
    return res;
  }

 private:
  struct Pending {
    sensor_msgs::msg::dds_::Image_ image;
    Key key;
    double now;
  };

  void replayed(const ServoReply& r) {
    replayed_.push_back({r.stamp, r.twist, static_cast<int>(r.state), r.error_norm, r.decoded});
  }
  // the frame's status is there, its pose when the recording has poses, and its white frame
  // when the servo takes them and the recording has them
  bool complete(const Key& k) const {
    return std::find(statuses_.begin(), statuses_.end(), k) != statuses_.end() &&
           (!poses_in_file_ || std::find(poses_.begin(), poses_.end(), k) != poses_.end()) &&
           (!(o_.config.white_frame && white_recorded_) || white_of(k) != whites_.end());
  }
  std::deque<std::pair<Key, sensor_msgs::msg::dds_::Image_>>::const_iterator white_of(const Key& k) const {
    return std::find_if(whites_.begin(), whites_.end(), [&](const auto& w) { return w.first == k; });
  }
  void seen(std::deque<Key>& keys, const Key& k) {
    keys.push_back(k);
    if (keys.size() > 64) keys.pop_front();
    if (pending_ && complete(pending_->key)) flush();
  }
  // the waiting image to the servo
  void flush() {
    if (!pending_) return;
    const Pending p = std::move(*pending_);
    pending_.reset();
    const auto w = white_of(p.key);
    const ImageView white = w == whites_.end() ? ImageView{} : image_view(w->second);
    const ServoReply r = machine_->on_image(image_view(p.image), p.now, w == whites_.end() ? nullptr : &white);
    if (!r.notice.empty()) std::fprintf(stderr, "servo replay: %s\n", r.notice.c_str());
    if (r.answer) replayed(r);
  }

  const ReplayOptions& o_;
  std::unique_ptr<ServoStateMachine> machine_;
  std::optional<std::uint64_t> t0_;
  long images_ = 0;
  std::optional<Stamp> last_image_;  // the latest image stamp fed
  // the recorded LOST statuses by stamp (bounded: a recording is untrusted), and the replay's own
  static constexpr std::size_t kMaxLostStamps = 1u << 16;
  std::map<Key, long> lost_recorded_at_;
  long lost_replayed_ = 0;
  TwistAt ready_;
  std::vector<TwistAt> recorded_, replayed_;
  std::optional<Pending> pending_;         // an image waiting for its frame's status and pose
  std::deque<Key> statuses_, poses_;       // the stamps of the latest 64 of each
  bool poses_in_file_ = false;
  // the latest white reference frames by stamp (the servo's --white-frame), bounded as live
  static constexpr std::size_t kMaxWhites = 4;
  std::deque<std::pair<Key, sensor_msgs::msg::dds_::Image_>> whites_;
  bool white_recorded_ = false;  // the recording holds white frames (kept only when the servo takes them)
};

}  // namespace

ReplayResult run_replay(const ReplayOptions& options) {
  Replay replay(options);
  mcap::ReadLimits limits;
  limits.allow_truncated = true;  // a killed recorder's file: its complete chunks are replayed
  const mcap::ReadSummary s = mcap::read_mcap_file(
      options.recording, [&](const mcap::Channel& c, const mcap::MessageView& m) { replay.on_message(c, m); }, limits);
  if (s.profile != "ros2")
    std::fprintf(stderr, "servo replay: %s: profile '%s', not ros2; read as the cell's topics anyway\n",
                 options.recording.c_str(), s.profile.c_str());
  const auto stopped = s.metadata.find(cell_record::kStoppedMetadata);
  // every image would be rejected: the run was not one with white frames (said before anything is written)
  if (options.config.white_frame && replay.images() > 0 && !replay.white_recorded())
    throw std::runtime_error(options.recording.string() + ": no white reference frames (" +
                             cell_record::ros_topic_name(cell_dds::kWhiteImageTopic) +
                             ") to replay --white-frame with: the run was recorded without them");
  ReplayResult r = replay.compare_and_write(s.truncated.has_value() || stopped != s.metadata.end());
  r.truncated = s.truncated;
  if (stopped != s.metadata.end()) {
    const auto why = stopped->second.find("reason");
    r.stopped = common::printable(why == stopped->second.end() ? std::string("no reason given") : why->second, 300);
  }
  return r;
}

}  // namespace servo
