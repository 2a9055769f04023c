// A run recorded as rosbag2 records it: an MCAP file in the ROS 2 profile (docs/topics.md,
// Record, inspect, replay). Each topic is a channel ("/camera/image_raw") with its type's
// schema (ros2msg: the .msg text and every type it uses), its CDR bytes as they go on the
// wire, the QoS its writer offers (offered_qos_profiles) and its REP-2011 type hash
// (topic_type_hash); each message carries its log and publish times.
#pragma once

#include <fastdds/rtps/common/SerializedPayload.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <thread>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "dds/endpoint.hpp"
#include "dds/topics.hpp"
#include "dds/type_hash.hpp"
#include "mcap/mcap_writer.hpp"

namespace cell_record {

struct RecordOptions {
  std::filesystem::path file;
  bool images = true;  // false: the image topics are left out (--record-no-images), for long runs
  std::string image_topic = cell_dds::kImageTopic;  // the camera's topic, namespaced as the cell's
  std::string white_image_topic = cell_dds::kWhiteImageTopic;  // its white reference frames, the same
  // recording stops (said once) when the file reaches this size; the run goes on
  std::uint64_t max_bytes = 16ull << 30;
};

// The ros2msg schema of a type ("sensor_msgs/msg/Image"): its definition, then each type it
// uses after a line of 80 '=' and "MSG: pkg/Type", as rosbag2 writes them. The project's
// own types keep their .msg text (idl/ros2/cell_msgs, constants included); the others are
// written from the type descriptions the type hashes come from.
std::string ros2msg_schema(const std::string& ros_type);
// The .msg text of one type, without the types it uses.
std::string msg_definition(const std::string& ros_type);
// offered_qos_profiles as rosbag2 (Jazzy) writes it: a YAML list of one profile.
std::string offered_qos_yaml(cell_dds::Stream stream);
// "rt/camera/image_raw" -> "/camera/image_raw"
std::string ros_topic_name(const std::string& dds_topic);

// Nanoseconds since the Unix epoch, as rosbag2 stamps what it records.
std::uint64_t wall_ns();

// The metadata record a recording that stopped before the run ended closes with (the size
// limit, a failed write): {"reason": why}. The last messages before the stop may then answer
// frames whose images are not in the file (a twist is queued as it arrives, its image's
// megabyte after it), as in a truncated file; `servo replay` counts those apart.
inline constexpr const char* kStoppedMetadata = "recording_stopped";

class Recorder {
 public:
  // Opens the file; throws std::runtime_error (one line naming it) when it cannot.
  // `metadata` goes into a "cellsim" metadata record (scenario, seed, mode).
  // The file is written as mcap::Writer writes it: never over a file that exists, into
  // FILE.partial until closed.
  Recorder(RecordOptions options, const mcap::KeyValues& metadata);

  ~Recorder();

  // One message on `dds_topic`, serialised as the wire carries it and handed to the
  // recorder's own thread, which chunks, checksums and writes it: the loop pays for one copy
  // of the bytes. Thread-safe: the DDS listeners record what they receive while the service
  // loop records what it sends. Waits only when kMaxQueuedBytes are still unwritten
  // (a lockstep plane run with images is 300 MB; the writer catches up in the idle time).
  // `log_ns`: the log time (an in-process run gives its simulated time); by default the
  // wall clock when the message is queued, as rosbag2 logs what it receives.
  template <typename PubSubType>
  void record(const std::string& dds_topic, cell_dds::Stream stream, const typename PubSubType::type& sample,
              std::uint64_t publish_ns, std::optional<std::uint64_t> log_ns = std::nullopt) {
    if (!wanted(dds_topic)) return;
    PubSubType type;
    auto& s = const_cast<typename PubSubType::type&>(sample);  // Fast DDS 2's serialize takes void*
    auto payload = std::make_unique<eprosima::fastrtps::rtps::SerializedPayload_t>(type.getSerializedSizeProvider(&s)());
    if (!type.serialize(&s, payload.get())) return;
    enqueue({dds_topic, cell_dds::ros_type_name(type.getName()), stream, std::move(payload), log_ns, publish_ns});
  }

  // Writes what is queued, the summary and the footer; what was recorded, per topic. Idempotent;
  // never throws: a recording that failed says so in the summary's `problem`.
  mcap::WriteSummary close();
  // Start-up failed: nothing was recorded, and the partial file is removed.
  void abandon();
  static constexpr std::size_t kMaxQueuedBytes = 256u << 20;
  const std::filesystem::path& file() const { return options_.file; }
  // "FILE (N.N MB, M messages on K topics)", and why it stopped or is short, for the summary line
  std::string describe(const mcap::WriteSummary& s) const;
  // "/camera/image_raw 324, /clock 324, ...": what an MCAP reader must find, per topic
  static std::string topic_counts(const mcap::WriteSummary& s);

 private:
  struct Pending {
    std::string dds_topic, ros_type;
    cell_dds::Stream stream;
    std::unique_ptr<eprosima::fastrtps::rtps::SerializedPayload_t> bytes;  // the CDR, as serialised
    std::optional<std::uint64_t> log_ns;
    std::uint64_t publish_ns;
  };
  bool wanted(const std::string& dds_topic) const;
  void enqueue(Pending&& p);
  void drain();                  // the writer thread
  void write(const Pending& p);  // on the writer thread only

  RecordOptions options_;
  std::mutex m_;
  std::condition_variable queued_, room_;
  std::deque<Pending> queue_;
  std::size_t queued_bytes_ = 0;
  bool stopping_ = false;
  std::thread thread_;
  std::unique_ptr<mcap::Writer> writer_;
  std::map<std::string, std::uint16_t> schemas_;   // by ROS type
  std::map<std::string, std::uint16_t> channels_;  // by DDS topic
  std::map<std::uint16_t, std::uint32_t> sequences_;
  std::atomic<bool> stopped_{false};  // by the size limit or a failed write: stop_reason_ says which
  std::string stop_reason_;           // written by the writer thread before stopped_
  mcap::WriteSummary summary_;
  bool closed_ = false;
};

// Records every sample `w` writes (nothing when `r` is null).
template <typename PubSubType>
void record_writes(Recorder* r, cell_dds::Writer<PubSubType>& w, cell_dds::Stream stream) {
  if (!r) return;
  const std::string topic = w.topic();
  w.tap([r, topic, stream](const typename PubSubType::type& m) { r->record<PubSubType>(topic, stream, m, wall_ns()); });
}
// A reader's tap that records every sample it takes, at its writer's source time (nothing
// when `r` is null). `stream` is the topic's QoS in the topic map, which its writer offers.
template <typename PubSubType>
typename cell_dds::Reader<PubSubType>::Tap recording(Recorder* r, const std::string& topic, cell_dds::Stream stream) {
  if (!r) return {};
  return [r, topic, stream](const typename PubSubType::type& m, std::uint64_t source_ns) {
    r->record<PubSubType>(topic, stream, m, source_ns != 0 ? source_ns : wall_ns());
  };
}

// A reader of `topic` with the topic map's QoS for `stream` whose samples are also recorded
// (when `r` is not null), at the QoS its writer offers.
template <typename PubSubType>
std::unique_ptr<cell_dds::Reader<PubSubType>> recorded_reader(eprosima::fastdds::dds::DomainParticipant& p,
                                                              const std::string& topic, cell_dds::Stream stream,
                                                              typename cell_dds::Reader<PubSubType>::Callback on_sample,
                                                              Recorder* r) {
  return std::make_unique<cell_dds::Reader<PubSubType>>(p, topic, cell_dds::reader_qos(stream), std::move(on_sample),
                                                        recording<PubSubType>(r, topic, stream));
}

}  // namespace cell_record
