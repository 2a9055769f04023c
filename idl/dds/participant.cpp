#include "dds/participant.hpp"

#include <cstdlib>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>
#include <fastrtps/xmlparser/XMLProfileManager.h>
#include <stdexcept>

namespace cell_dds {

using namespace eprosima::fastdds::dds;

int domain_id_from_env(int fallback) {
  const char* env = std::getenv("ROS_DOMAIN_ID");
  if (env == nullptr || *env == '\0') return fallback;
  char* end = nullptr;
  const long v = std::strtol(env, &end, 10);
  if (*end != '\0' || v < 0 || v > 232) throw std::runtime_error(std::string("ROS_DOMAIN_ID='") + env + "' is not a domain id (0..232)");
  return static_cast<int>(v);
}

void ParticipantDeleter::operator()(DomainParticipant* p) const {
  if (p == nullptr) return;
  p->delete_contained_entities();
  DomainParticipantFactory::get_instance()->delete_participant(p);
}

ParticipantPtr make_participant(const ParticipantOptions& o) {
  if (!o.intraprocess) {
    // library-wide: must be set before the first participant is created
    eprosima::fastrtps::LibrarySettingsAttributes lib;
    lib.intraprocess_delivery = eprosima::fastrtps::INTRAPROCESS_OFF;
    eprosima::fastrtps::xmlparser::XMLProfileManager::library_settings(lib);
  }
  DomainParticipantQos qos = PARTICIPANT_QOS_DEFAULT;
  qos.name(o.name);
  if (o.loopback_only) {
    qos.transport().use_builtin_transports = false;
    auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
    udp->interfaceWhiteList.emplace_back("127.0.0.1");
    udp->maxInitialPeersRange = 32;  // up to 32 participants per host answer the initial peer
    qos.transport().user_transports.push_back(udp);
    // large frames between processes of one host go through shared memory
    auto shm = std::make_shared<eprosima::fastdds::rtps::SharedMemTransportDescriptor>();
    shm->segment_size(8 * 1024 * 1024);
    qos.transport().user_transports.push_back(shm);
    eprosima::fastrtps::rtps::Locator_t peer;
    peer.kind = LOCATOR_KIND_UDPv4;
    eprosima::fastrtps::rtps::IPLocator::setIPv4(peer, 127, 0, 0, 1);
    qos.wire_protocol().builtin.initialPeersList.push_back(peer);
  }
  DomainParticipant* p = DomainParticipantFactory::get_instance()->create_participant(o.domain_id, qos);
  if (p == nullptr)
    throw std::runtime_error("cannot create a DDS participant '" + o.name + "' on domain " + std::to_string(o.domain_id));
  return ParticipantPtr(p);
}

void register_type(DomainParticipant& participant, TypeSupport type) {
  type->auto_fill_type_information(false);
  type->auto_fill_type_object(false);
  if (type.register_type(&participant) != ReturnCode_t::RETCODE_OK)
    throw std::runtime_error("cannot register DDS type " + type.get_type_name());
}

}  // namespace cell_dds
