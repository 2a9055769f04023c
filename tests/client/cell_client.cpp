// An outside DDS client of the cell, linked only to Fast DDS and the types generated from
// idl/ (none of the project's libraries): it commands the simulator on rt/sim/control and
// watches the servo on rt/servo/status, as any user's tool would.
//
//   cell_client [--domain N] [--timeout S] [--help]   teach, go to the initial pose, start,
//                                                    and wait for CONVERGED (exit 0) or give up (1)
#include <atomic>
#include <cerrno>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>
#include <string>
#include <thread>

#include "cell_msgsPubSubTypes.h"

using namespace eprosima::fastdds::dds;
namespace SS = cell_msgs::msg::dds_::ServoStatus_Constants;
namespace SC = cell_msgs::msg::dds_::SimControl_Constants;

namespace {

const char* state_name(uint8_t s) {
  switch (s) {
    case SS::IDLE: return "IDLE";
    case SS::TEACHING: return "TEACHING";
    case SS::SERVOING: return "SERVOING";
    case SS::CONVERGED: return "CONVERGED";
    case SS::LOST: return "LOST";
    case SS::STOPPED: return "STOPPED";
  }
  return "?";
}

class StatusListener : public DataReaderListener {
 public:
  std::atomic<bool> converged{false};
  std::atomic<long> seen{0};
  void on_data_available(DataReader* reader) override {
    cell_msgs::msg::dds_::ServoStatus_ s;
    SampleInfo info;
    while (reader->take_next_sample(&s, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      if (++seen % 25 == 1 || s.state() == SS::CONVERGED)
        std::printf("status: %s, iteration %u, |e| %.3g, decoded %u, matched %u %s\n", state_name(s.state()), s.iteration(),
                    s.error_norm(), s.decoded(), s.matched(), s.reason().c_str());
      if (s.state() == SS::CONVERGED) converged = true;
    }
  }
};

constexpr const char* kUsage =
    "usage: cell_client [--domain N] [--timeout S] [--first-match]\n"
    "  Joins DDS domain N (default: ROS_DOMAIN_ID, else 0) over loopback, waits for a cellsim (the\n"
    "  reader of rt/sim/control) and a servo (its status), sends TEACH, RESET initial and START, and\n"
    "  waits for CONVERGED on rt/servo/status: exit 0, or 1 after S seconds (default 120).\n"
    "  --first-match: send the moment the first reader of rt/sim/control matches, servo or not (as\n"
    "  `ros2 topic pub --once -w 1`).\n";

// A whole decimal integer in [lo, hi], or nullopt.
bool parse_int(const char* text, long lo, long hi, long& out) {
  if (!text || !*text) return false;
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(text, &end, 10);
  if (errno != 0 || *end != '\0' || v < lo || v > hi) return false;
  out = v;
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  // 231, the cell's kMaxDomainId (idl/dds/participant.hpp; this client is written as an outside
  // one, on the generated types alone): the largest domain whose participants' ports fit in 16 bits
  constexpr long kMaxDomainId = 231;
  long domain = 0;
  if (const char* env = std::getenv("ROS_DOMAIN_ID"); env && *env && !parse_int(env, 0, kMaxDomainId, domain)) {
    std::fprintf(stderr, "cell_client: ROS_DOMAIN_ID '%.40s' is not a domain id (0 to %ld)\n", env, kMaxDomainId);
    return 2;
  }
  double timeout_s = 120;
  bool first_match = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help") {
      std::printf("%s", kUsage);
      return 0;
    }
    if ((a == "--domain" || a == "--timeout") && i + 1 >= argc) {
      std::fprintf(stderr, "cell_client: %s needs a value (see --help)\n", a.c_str());
      return 2;
    }
    if (a == "--first-match") {
      first_match = true;
    } else if (a == "--domain") {
      if (!parse_int(argv[++i], 0, kMaxDomainId, domain)) {
        std::fprintf(stderr, "cell_client: --domain '%.40s' is not a domain id (0 to %ld)\n", argv[i], kMaxDomainId);
        return 2;
      }
    } else if (a == "--timeout") {
      char* end = nullptr;
      timeout_s = std::strtod(argv[++i], &end);
      if (*end != '\0' || !std::isfinite(timeout_s) || timeout_s <= 0 || timeout_s > 1e6) {
        std::fprintf(stderr, "cell_client: --timeout '%.40s' must be a number of seconds in (0, 1e6]\n", argv[i]);
        return 2;
      }
    } else {
      std::fprintf(stderr, "cell_client: unknown argument '%.40s' (see --help)\n", a.c_str());
      return 2;
    }
  }

  // The cell's services discover peers on this host through 127.0.0.1 (no multicast onto
  // the network); a client joins the same way.
  DomainParticipantQos pq = PARTICIPANT_QOS_DEFAULT;
  pq.name("cell_client");
  pq.transport().use_builtin_transports = false;
  auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
  udp->interfaceWhiteList.emplace_back("127.0.0.1");
  udp->maxInitialPeersRange = 32;
  pq.transport().user_transports.push_back(udp);
  pq.transport().user_transports.push_back(std::make_shared<eprosima::fastdds::rtps::SharedMemTransportDescriptor>());
  eprosima::fastrtps::rtps::Locator_t peer;
  peer.kind = LOCATOR_KIND_UDPv4;
  eprosima::fastrtps::rtps::IPLocator::setIPv4(peer, 127, 0, 0, 1);
  pq.wire_protocol().builtin.initialPeersList.push_back(peer);
  DomainParticipant* p = DomainParticipantFactory::get_instance()->create_participant(static_cast<int>(domain), pq);
  if (!p) {
    std::fprintf(stderr, "cell_client: cannot join DDS domain %ld\n", domain);
    return 2;
  }
  // no type information on the wire (what Cyclone DDS and the cell expect)
  TypeSupport control_type(new cell_msgs::msg::dds_::SimControl_PubSubType());
  TypeSupport status_type(new cell_msgs::msg::dds_::ServoStatus_PubSubType());
  for (TypeSupport* t : {&control_type, &status_type}) {
    (*t)->auto_fill_type_information(false);
    (*t)->auto_fill_type_object(false);
    t->register_type(p);
  }
  Topic* control_topic = p->create_topic("rt/sim/control", control_type.get_type_name(), TOPIC_QOS_DEFAULT);
  Topic* status_topic = p->create_topic("rt/servo/status", status_type.get_type_name(), TOPIC_QOS_DEFAULT);

  DataWriterQos wq = DATAWRITER_QOS_DEFAULT;
  wq.reliability().kind = RELIABLE_RELIABILITY_QOS;
  wq.history().kind = KEEP_LAST_HISTORY_QOS;
  wq.history().depth = 16;
  DataWriter* control = p->create_publisher(PUBLISHER_QOS_DEFAULT)->create_datawriter(control_topic, wq);
  DataReaderQos rq = DATAREADER_QOS_DEFAULT;
  rq.reliability().kind = RELIABLE_RELIABILITY_QOS;
  rq.durability().kind = TRANSIENT_LOCAL_DURABILITY_QOS;
  rq.history().kind = KEEP_LAST_HISTORY_QOS;
  rq.history().depth = 1;
  StatusListener listener;
  DataReader* status = p->create_subscriber(SUBSCRIBER_QOS_DEFAULT)->create_datareader(status_topic, rq, &listener);
  if (!control || !status) {
    std::fprintf(stderr, "cell_client: cannot create the DDS endpoints\n");
    return 2;
  }

  // the simulator is the one reader of the control topic (the servo learns the commands it
  // obeyed on rt/sim/accepted); the servo says it is there on its latched status
  const auto start = std::chrono::steady_clock::now();
  const auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  std::printf("cell_client: waiting for %s on domain %ld\n",
              first_match ? "the first reader of rt/sim/control" : "cellsim (rt/sim/control) and a servo (rt/servo/status)",
              domain);
  std::fflush(stdout);
  PublicationMatchedStatus pm;
  const auto ready = [&] { return pm.current_count >= 1 && (first_match || listener.seen > 0); };
  double next_note_s = 5;
  do {
    control->get_publication_matched_status(pm);
    if (!ready() && elapsed() >= next_note_s) {
      std::printf("cell_client: after %.0f s, %s on rt/sim/control, %s on rt/servo/status (are they running, with the same "
                  "ROS_DOMAIN_ID?)\n",
                  elapsed(), pm.current_count ? "a reader" : "no reader", listener.seen > 0 ? "a servo" : "no servo");
      std::fflush(stdout);
      next_note_s += 10;
    }
    if (!ready()) std::this_thread::sleep_for(std::chrono::milliseconds(first_match ? 1 : 50));
  } while (!ready() && elapsed() < timeout_s);
  if (!ready()) {
    std::fprintf(stderr, "cell_client: the simulator and the servo are not both on domain %ld after %.0f s\n", domain,
                 timeout_s);
    return 1;
  }
  // --first-match: at once, as `ros2 topic pub --once -w 1` does
  if (!first_match) std::this_thread::sleep_for(std::chrono::milliseconds(200));
  for (auto [cmd, arg] : {std::pair<uint8_t, const char*>{SC::TEACH, ""}, {SC::RESET, "initial"}, {SC::START, ""}}) {
    cell_msgs::msg::dds_::SimControl_ c;
    c.command(cmd);
    c.argument(arg);
    control->write(&c);
    std::printf("sent %s\n", cmd == SC::TEACH ? "TEACH" : cmd == SC::RESET ? "RESET initial" : "START");
  }
  while (!listener.converged && elapsed() < timeout_s) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const bool ok = listener.converged;
  cell_msgs::msg::dds_::SimControl_ pause;
  pause.command(SC::PAUSE);
  control->write(&pause);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  p->delete_contained_entities();
  DomainParticipantFactory::get_instance()->delete_participant(p);
  std::printf(ok ? "cell_client: the servo converged\n" : "cell_client: no convergence within %.0f s\n", timeout_s);
  return ok ? 0 : 1;
}
