// DDS edge helpers shared by the two services, the tests and the example client:
// participants, topics and QoS set up the same way everywhere. Only apps link this.
#pragma once

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <memory>
#include <string>

namespace cell_dds {

struct ParticipantOptions {
  int domain_id = 0;
  std::string name = "cell";
  // Loopback only by default: a CI machine must not send discovery traffic to other hosts.
  // With false, every interface is used (sim and servo on different hosts).
  bool loopback_only = true;
  // Deliver between entities of one process through the real transport, not a shortcut,
  // so a test with two participants in one process exercises what two processes would.
  bool intraprocess = true;
};

// Domain id from $ROS_DOMAIN_ID when set (and valid), otherwise `fallback`.
int domain_id_from_env(int fallback);

struct ParticipantDeleter {
  void operator()(eprosima::fastdds::dds::DomainParticipant* p) const;
};
using ParticipantPtr = std::unique_ptr<eprosima::fastdds::dds::DomainParticipant, ParticipantDeleter>;

// Throws std::runtime_error when the participant cannot be created.
ParticipantPtr make_participant(const ParticipantOptions& options);

// Registers a generated type with no type information announced: Fast DDS 2.9 writers
// that send TypeObject/TypeInformation are rejected by Cyclone DDS 0.10.
void register_type(eprosima::fastdds::dds::DomainParticipant& participant,
                   eprosima::fastdds::dds::TypeSupport type);

}  // namespace cell_dds
