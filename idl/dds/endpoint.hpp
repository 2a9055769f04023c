// Typed DDS endpoints over the generated types: one writer or reader per topic, RAII over
// the Fast DDS entities, constructors that throw when an entity cannot be created.
#pragma once

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <algorithm>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <chrono>
#include <string>

#include "dds/participant.hpp"
#include "dds/topics.hpp"
#include "dds/type_hash.hpp"

namespace cell_dds {

// A generated type whose received samples are bounded in bytes (max_sample_bytes): a longer
// one is refused before it is deserialised, and Fast DDS drops it (issue 40, item 4).
template <typename PubSubType>
class BoundedType : public PubSubType {
 public:
  BoundedType() : max_bytes_(max_sample_bytes(PubSubType().getName())) {}
  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) override {
    if (payload == nullptr || payload->length > max_bytes_) return false;
    return PubSubType::deserialize(payload, data);
  }

 private:
  std::uint32_t max_bytes_;
};

// The topic of that name, created (with its type registered) on first use.
template <typename PubSubType>
eprosima::fastdds::dds::Topic* topic_for(eprosima::fastdds::dds::DomainParticipant& p, const std::string& name) {
  using namespace eprosima::fastdds::dds;
  eprosima::fastdds::dds::TypeSupport type(new BoundedType<PubSubType>());
  if (!p.find_type(type.get_type_name()).empty()) {
    // already registered
  } else {
    register_type(p, type);
  }
  if (auto* d = p.lookup_topicdescription(name)) return dynamic_cast<Topic*>(d);
  Topic* t = p.create_topic(name, type.get_type_name(), TOPIC_QOS_DEFAULT);
  if (t == nullptr) throw std::runtime_error("cannot create DDS topic " + name);
  return t;
}

template <typename PubSubType>
class Writer {
 public:
  using Data = typename PubSubType::type;
  Writer(eprosima::fastdds::dds::DomainParticipant& p, const std::string& topic,
         const eprosima::fastdds::dds::DataWriterQos& qos)
      : participant_(p), name_(topic) {
    publisher_ = p.create_publisher(eprosima::fastdds::dds::PUBLISHER_QOS_DEFAULT);
    if (!publisher_) throw std::runtime_error("cannot create a DDS publisher for " + topic);
    eprosima::fastdds::dds::DataWriterQos q = qos;
    q.user_data().data_vec(type_hash_user_data(PubSubType().getName()));  // REP-2011: typehash=...;
    writer_ = publisher_->create_datawriter(topic_for<PubSubType>(p, topic), q);
    if (!writer_) throw std::runtime_error("cannot create a DDS writer for " + topic);
  }
  ~Writer() {
    publisher_->delete_datawriter(writer_);
    participant_.delete_publisher(publisher_);
  }
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  // what is written, seen just before each write (a recorder: record/recorder.hpp). Before,
  // not after: a synchronous write returns once the sample is delivered, and the answer to it
  // (the servo's twist to an image) can be heard, and recorded, before the write returns; a
  // recording cut there (a full disk, a kill) then held an answer without its question. A
  // write that fails (rare: a reliable writer's history full past its blocking time) is
  // recorded all the same, and its replay answers a frame the recording has no answer to.
  using Tap = std::function<void(const Data&)>;
  void tap(Tap t) { tap_ = std::move(t); }
  bool write(Data& sample) {
    if (tap_) tap_(sample);
    return writer_->write(&sample);
  }
  // Waits (bounded) until every matched reliable reader has acknowledged what was written: a
  // process that writes its last word and exits would otherwise take it down with its writer.
  bool flush(std::chrono::milliseconds limit) {
    const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(limit).count();
    return writer_->wait_for_acknowledgments(eprosima::fastrtps::Duration_t(
               static_cast<int32_t>(ns / 1000000000), static_cast<uint32_t>(ns % 1000000000))) ==
           eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK;
  }
  int matched() const {
    eprosima::fastdds::dds::PublicationMatchedStatus s;
    writer_->get_publication_matched_status(s);
    return s.current_count;
  }
  const std::string& topic() const { return name_; }
  eprosima::fastrtps::rtps::GUID_t guid() const { return writer_->guid(); }

 private:
  eprosima::fastdds::dds::DomainParticipant& participant_;
  std::string name_;
  Tap tap_;
  eprosima::fastdds::dds::Publisher* publisher_ = nullptr;
  eprosima::fastdds::dds::DataWriter* writer_ = nullptr;
};

// Calls `on_sample` from Fast DDS's listener thread for every valid sample.
template <typename PubSubType>
class Reader : private eprosima::fastdds::dds::DataReaderListener {
 public:
  using Data = typename PubSubType::type;
  using Callback = std::function<void(Data&&)>;
  // what is received, with its writer's source timestamp (ns since the epoch), before the
  // callback takes it (a recorder)
  using Tap = std::function<void(const Data&, std::uint64_t source_ns)>;
  Reader(eprosima::fastdds::dds::DomainParticipant& p, const std::string& topic,
         const eprosima::fastdds::dds::DataReaderQos& qos, Callback on_sample, Tap tap = {})
      : participant_(p), name_(topic), on_sample_(std::move(on_sample)), tap_(std::move(tap)) {
    subscriber_ = p.create_subscriber(eprosima::fastdds::dds::SUBSCRIBER_QOS_DEFAULT);
    if (!subscriber_) throw std::runtime_error("cannot create a DDS subscriber for " + topic);
    eprosima::fastdds::dds::DataReaderQos q = qos;
    q.user_data().data_vec(type_hash_user_data(PubSubType().getName()));
    // small messages: each sample's buffer is freed once taken. The default pool keeps every
    // buffer at the largest size it ever held (64 statuses of 10 MB were 640 MB until exit);
    // images keep it, one VGA frame a buffer, allocated once
    if (max_sample_bytes(PubSubType().getName()) <= (4u << 20))
      q.endpoint().history_memory_policy = eprosima::fastrtps::rtps::DYNAMIC_RESERVE_MEMORY_MODE;
    // no resource_limits below the history: KEEP_LAST already bounds what a flood can queue,
    // and a reliable reader whose max_samples equals its depth stalls (it refused samples and
    // a writer's KEEP_LAST 1 history no longer had them to repair: statuses stopped arriving)
    reader_ = subscriber_->create_datareader(topic_for<PubSubType>(p, topic), q, this);
    if (!reader_) throw std::runtime_error("cannot create a DDS reader for " + topic);
  }
  ~Reader() {
    reader_->set_listener(nullptr);
    subscriber_->delete_datareader(reader_);
    participant_.delete_subscriber(subscriber_);
  }
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;

  eprosima::fastrtps::rtps::GUID_t guid() const { return reader_->guid(); }
  const std::string& topic() const { return name_; }
  int matched() const {
    eprosima::fastdds::dds::SubscriptionMatchedStatus s;
    reader_->get_subscription_matched_status(s);
    return s.current_count;
  }

 private:
  void on_data_available(eprosima::fastdds::dds::DataReader* reader) override {
    Data sample;
    eprosima::fastdds::dds::SampleInfo info;
    while (reader->take_next_sample(&sample, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      if (tap_) tap_(sample, static_cast<std::uint64_t>(std::max<std::int64_t>(0, info.source_timestamp.to_ns())));
      on_sample_(std::move(sample));
    }
  }

  eprosima::fastdds::dds::DomainParticipant& participant_;
  std::string name_;
  Callback on_sample_;
  Tap tap_;
  eprosima::fastdds::dds::Subscriber* subscriber_ = nullptr;
  eprosima::fastdds::dds::DataReader* reader_ = nullptr;
};

}  // namespace cell_dds
