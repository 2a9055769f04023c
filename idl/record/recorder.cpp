#include "record/recorder.hpp"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cstdio>
#include <set>
#include <sstream>
#include <stdexcept>

namespace cell_record {

// idl/ros2/cell_msgs/msg/*.msg, compiled in (idl/CMakeLists.txt), by "cell_msgs/msg/Type"
const std::map<std::string, std::string>& shipped_msg_files();

namespace {

std::string msg_spelling(const cell_dds::FieldDescription& f) {
  static const std::map<int, std::string> basic{{2, "int8"},    {3, "uint8"},    {4, "int16"},  {5, "uint16"},
                                                {6, "int32"},   {7, "uint32"},   {8, "int64"},  {9, "uint64"},
                                                {10, "float32"}, {11, "float64"}, {15, "bool"}, {16, "byte"},
                                                {17, "string"}, {18, "wstring"}, {21, "string"}, {22, "wstring"}};
  const int base = f.type_id % 48;
  const int kind = f.type_id - base;  // 0 single, 48 array, 96 bounded sequence, 144 sequence
  std::string t;
  if (base == 1) {
    // "pkg/msg/Type" is spelled "pkg/Type" in a .msg file
    const std::string& n = f.nested_type_name;
    const auto first = n.find('/'), last = n.rfind('/');
    t = n.substr(0, first) + "/" + n.substr(last + 1);
  } else {
    const auto it = basic.find(base);
    if (it == basic.end()) throw std::runtime_error("field " + f.name + ": type id " + std::to_string(f.type_id) + " has no .msg spelling");
    t = it->second;
    if (base == 21 || base == 22) t += "<=" + std::to_string(f.string_capacity);
  }
  if (kind == 48) t += "[" + std::to_string(f.capacity) + "]";
  if (kind == 96) t += "[<=" + std::to_string(f.capacity) + "]";
  if (kind == 144) t += "[]";
  return t;
}

// the types `ros_type` uses, each once, in the order a depth-first walk meets them
void dependencies(const std::string& ros_type, std::vector<std::string>& order, std::set<std::string>& seen) {
  const auto& types = cell_dds::project_type_descriptions();
  const auto it = types.find(ros_type);
  if (it == types.end()) throw std::runtime_error(ros_type + ": not one of the project's types");
  for (const auto& f : it->second) {
    if (f.nested_type_name.empty() || seen.count(f.nested_type_name)) continue;
    seen.insert(f.nested_type_name);
    order.push_back(f.nested_type_name);
    dependencies(f.nested_type_name, order, seen);
  }
}

}  // namespace

std::string msg_definition(const std::string& ros_type) {
  if (const auto it = shipped_msg_files().find(ros_type); it != shipped_msg_files().end()) return it->second;
  const auto& types = cell_dds::project_type_descriptions();
  const auto it = types.find(ros_type);
  if (it == types.end()) throw std::runtime_error(ros_type + ": not one of the project's types");
  std::string text;
  for (const auto& f : it->second) text += msg_spelling(f) + " " + f.name + "\n";
  return text;
}

std::string ros2msg_schema(const std::string& ros_type) {
  std::vector<std::string> order;
  std::set<std::string> seen{ros_type};
  dependencies(ros_type, order, seen);
  std::string text = msg_definition(ros_type);
  for (const auto& dep : order) {
    if (!text.empty() && text.back() != '\n') text += '\n';
    // "MSG: pkg/Type", as the .msg files spell a field's type and as rosbag2 and Foxglove read it
    const std::string spelled = dep.substr(0, dep.find('/')) + dep.substr(dep.rfind('/'));
    text += std::string(80, '=') + "\nMSG: " + spelled + "\n" + msg_definition(dep);
  }
  return text;
}

std::string offered_qos_yaml(cell_dds::Stream stream) {
  using namespace eprosima::fastdds::dds;
  const DataWriterQos q = cell_dds::writer_qos(stream);
  // ROS 2's "infinite" duration, as rosbag2 writes it
  const std::string infinite = "\n    sec: 9223372036\n    nsec: 854775807";
  std::ostringstream y;
  y << "- history: " << (q.history().kind == KEEP_ALL_HISTORY_QOS ? "keep_all" : "keep_last")
    << "\n  depth: " << q.history().depth
    << "\n  reliability: " << (q.reliability().kind == RELIABLE_RELIABILITY_QOS ? "reliable" : "best_effort")
    << "\n  durability: " << (q.durability().kind == TRANSIENT_LOCAL_DURABILITY_QOS ? "transient_local" : "volatile")
    << "\n  deadline:" << infinite << "\n  lifespan:" << infinite << "\n  liveliness: automatic"
    << "\n  liveliness_lease_duration:" << infinite << "\n  avoid_ros_namespace_conventions: false";
  return y.str();
}

std::string ros_topic_name(const std::string& dds_topic) {
  return dds_topic.rfind("rt/", 0) == 0 ? dds_topic.substr(2) : dds_topic;
}

std::uint64_t wall_ns() {
  return static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count());
}

Recorder::Recorder(RecordOptions options, const mcap::KeyValues& metadata) : options_(std::move(options)) {
  mcap::WriterOptions w;
  w.profile = "ros2";
  w.library = "cellsim (coded-light visual servoing cell)";
  writer_ = std::make_unique<mcap::Writer>(options_.file, w);
  writer_->add_metadata("cellsim", metadata);
  thread_ = std::thread([this] { drain(); });
}

Recorder::~Recorder() {
  try {
    close();
  } catch (...) {
    // a destructor must not throw; close() says what failed when it is called
  }
}

bool Recorder::wanted(const std::string& dds_topic) const {
  // the camera's topic exactly: under the namespace "camera/image_raw" every topic contains it
  return options_.images || (dds_topic != options_.image_topic && dds_topic != options_.white_image_topic);
}

void Recorder::enqueue(Pending&& p) {
  std::unique_lock<std::mutex> l(m_);
  room_.wait(l, [&] { return stopping_ || queued_bytes_ + p.bytes->length <= kMaxQueuedBytes || queue_.empty(); });
  if (stopping_) return;
  if (!p.log_ns) p.log_ns = wall_ns();  // under the lock: log times rise in the order the queue is written
  queued_bytes_ += p.bytes->length;
  queue_.push_back(std::move(p));
  queued_.notify_one();
}

void Recorder::drain() {
  // the loop comes first: the writer yields to it (nice 10), and in lockstep a core is idle
  // while the other process renders or decodes. Not SCHED_IDLE: on a loaded machine that
  // starved the writer and held the loop at a full queue (an experiment took 48 s for 4)
  setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 10);
  std::unique_lock<std::mutex> l(m_);
  while (true) {
    queued_.wait(l, [&] { return stopping_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stopping, and all written
    Pending p = std::move(queue_.front());
    queue_.pop_front();
    l.unlock();
    try {
      write(p);
    } catch (const std::exception& e) {
      // a full disk: the run goes on, the recording stops, said once
      if (!stopped_) {
        stop_reason_ = e.what();
        stopped_ = true;
        std::fprintf(stderr, "cellsim: %s; recording stopped, the run goes on\n", e.what());
      }
    }
    l.lock();
    queued_bytes_ -= p.bytes->length;
    room_.notify_all();
  }
}

void Recorder::write(const Pending& p) {
  if (stopped_) return;
  if (writer_->bytes_written() + p.bytes->length > options_.max_bytes) {
    stop_reason_ = "stopped at the size limit (" + std::to_string(options_.max_bytes >> 20) + " MB)";
    stopped_ = true;
    std::fprintf(stderr, "cellsim: %s: recording %s; the run goes on\n", options_.file.c_str(), stop_reason_.c_str());
    return;
  }
  auto ch = channels_.find(p.dds_topic);
  if (ch == channels_.end()) {
    auto sc = schemas_.find(p.ros_type);
    if (sc == schemas_.end())
      sc = schemas_.emplace(p.ros_type, writer_->add_schema(p.ros_type, "ros2msg", ros2msg_schema(p.ros_type))).first;
    const mcap::KeyValues meta{{"offered_qos_profiles", offered_qos_yaml(p.stream)},
                               {"topic_type_hash", cell_dds::type_hash(p.ros_type, cell_dds::project_type_descriptions())}};
    ch = channels_.emplace(p.dds_topic, writer_->add_channel(sc->second, ros_topic_name(p.dds_topic), "cdr", meta)).first;
  }
  writer_->write_message(ch->second, sequences_[ch->second]++, *p.log_ns, p.publish_ns,
                         p.bytes->data, p.bytes->length);
}

mcap::WriteSummary Recorder::close() {
  {
    std::lock_guard<std::mutex> l(m_);
    if (closed_) return summary_;
    closed_ = true;
    stopping_ = true;  // what is queued is still written
  }
  queued_.notify_all();
  room_.notify_all();
  if (thread_.joinable()) thread_.join();
  if (stopped_) {
    try {
      writer_->add_metadata(kStoppedMetadata, {{"reason", stop_reason_}});
    } catch (const std::exception&) {
      // the disk is still full: the writer's problem says so, and the file ends at its last
      // complete record, which a reader names truncated
    }
  }
  summary_ = writer_->close();
  return summary_;
}

void Recorder::abandon() {
  {
    std::lock_guard<std::mutex> l(m_);
    if (closed_) return;
    closed_ = true;
    stopping_ = true;
    queue_.clear();
    queued_bytes_ = 0;
  }
  queued_.notify_all();
  room_.notify_all();
  if (thread_.joinable()) thread_.join();
  writer_->abandon();
}

std::string Recorder::topic_counts(const mcap::WriteSummary& s) {
  std::string counts;
  for (const auto& [t, n] : s.topic_messages) counts += (counts.empty() ? "" : ", ") + t + " " + std::to_string(n);
  return counts;
}

std::string Recorder::describe(const mcap::WriteSummary& s) const {
  char buf[160];
  std::snprintf(buf, sizeof buf, " (%.1f MB, %llu messages on %zu topics)", static_cast<double>(s.bytes) / 1e6,
                static_cast<unsigned long long>(s.messages), s.topic_messages.size());
  std::string out = s.file.string() + buf;
  // the size limit is said here; a failed write is in the writer's problem, said once
  if (stopped_ && s.problem.empty()) out += "; recording " + stop_reason_;
  if (!s.problem.empty()) out += s.problem == stop_reason_ ? "; recording stopped when a write failed (said above)" : "; " + s.problem;
  if (!s.complete) out += "; truncated: servo replay reads its complete chunks";
  return out;
}

}  // namespace cell_record
