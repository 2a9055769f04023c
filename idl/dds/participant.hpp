// DDS edge helpers shared by the two services, the tests and the example client:
// participants, topics and QoS set up the same way everywhere. Only apps link this.
#pragma once

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace cell_dds {

// Discovery as ROS 2 configures it (REP-2021 / Jazzy's variables):
//   LOCALHOST  UDP on 127.0.0.1 only, peers found by unicast on this host (the default: without
//              DDS-Security, a cell reachable from the network can be driven by anyone);
//   SUBNET     every interface, multicast discovery (ROS 2's default);
//   OFF        no automatic discovery at all: only the static peers.
// Static peers (addresses, unicast) are contacted in every range; with LOCALHOST they make
// the participant use every interface for them, multicast staying off.
enum class DiscoveryRange { kLocalhost, kSubnet, kOff };
struct Discovery {
  DiscoveryRange range = DiscoveryRange::kLocalhost;
  std::vector<std::string> static_peers;  // IPv4 addresses
};
const char* to_string(DiscoveryRange r);

// ROS_AUTOMATIC_DISCOVERY_RANGE (LOCALHOST | SUBNET | OFF | SYSTEM_DEFAULT = SUBNET),
// ROS_STATIC_PEERS ("a.b.c.d;e.f.g.h"), the legacy ROS_LOCALHOST_ONLY=1 (LOCALHOST, as Jazzy
// does). Null pointers are unset variables. Throws std::invalid_argument naming the variable.
Discovery parse_discovery(const char* range, const char* static_peers, const char* localhost_only);
// The same from this process's environment.
Discovery discovery_from_env();
// The command line's --discovery-range / --static-peers (empty: not given) over the
// environment's variables. Throws std::invalid_argument naming the flag or the variable.
Discovery discovery_from(const std::string& range_flag, const std::string& peers_flag);

// DDS-Security as ROS 2 (SROS2) configures it: ROS_SECURITY_ENABLE=true,
// ROS_SECURITY_STRATEGY=Enforce (a missing enclave is an error) or Permissive (run without
// security when the enclave is missing), ROS_SECURITY_KEYSTORE=DIR (bin/keystore), and the
// enclave DIR/enclaves/<name> (ROS_SECURITY_ENCLAVE_OVERRIDE, or the process's own name).
struct Security {
  bool enabled = false;
  bool enforce = true;
  std::string keystore;
  std::string enclave_override;
};
// From the environment; throws std::invalid_argument naming the variable.
Security security_from_env();

struct ParticipantOptions {
  int domain_id = 0;
  std::string name = "cell";
  Security security;    // off unless the caller takes it from the environment
  std::string enclave;  // the enclave's name (default: `name`)
  // LOCALHOST unless the caller says otherwise (the services take the ROS 2 variables and
  // their --discovery-range / --static-peers flags): a CI machine sends nothing to other hosts.
  Discovery discovery;
  // Deliver between entities of one process through the real transport, not a shortcut,
  // so a test with two participants in one process exercises what two processes would.
  bool intraprocess = true;
};

// Domain id from $ROS_DOMAIN_ID when set (and valid), otherwise `fallback`.
int domain_id_from_env(int fallback);
// The largest domain id: 7400 + 250 d + 11 + 2 x 63 (the participant ids the initial peers
// reach) must stay a port number, so 231, not the 232 of DDS's formula for one participant.
inline constexpr int kMaxDomainId = 231;
// --domain's text if given (it must be a domain id), else ROS_DOMAIN_ID, else 0. Throws
// std::runtime_error with one line naming the value.
int domain_id_from(const std::string& flag);

struct ParticipantDeleter {
  void operator()(eprosima::fastdds::dds::DomainParticipant* p) const;
};
using ParticipantPtr = std::unique_ptr<eprosima::fastdds::dds::DomainParticipant, ParticipantDeleter>;

// Throws std::runtime_error when the participant cannot be created.
ParticipantPtr make_participant(const ParticipantOptions& options);

// Removes from `dir` (/dev/shm) the shared-memory files Fast DDS leaves behind a process killed
// with SIGKILL: ports ("fastrtps_port7411") and senders' segments ("fastrtps_" and 16 hex
// digits), with their "_el" locks and "_mutex" semaphores, and data-sharing pools
// ("fast_datasharing_..."). Only this user's regular files at least `min_age` old (a file being
// created is neither mapped nor locked yet) that no live process maps or holds open, and for a
// port or segment only when its lock is this user's regular file and free: never a folder, a
// FIFO, a link, another user's file, or a semaphore that is not a regular file (issue 40,
// item 9). Returns the names removed. make_participant calls it once per process.
std::vector<std::string> remove_orphaned_shm_files(const std::filesystem::path& dir, std::chrono::seconds min_age);

// The shared-memory segment a participant makes. A sender's segment holds at most `buffers`
// buffers; with room for 2 x buffers + 1 messages some hole always fits the next message,
// whatever a dead reader still holds (docs/topics.md, Stopping): 512 buffers in 65 MB. Where
// /dev/shm is small (Docker's default is 64 MB) a participant takes at most an eighth of
// `free_bytes`, with as many buffers as keep that rule, and never fewer than 16.
struct ShmSize {
  std::uint32_t segment_bytes = 0, buffers = 0;
};
ShmSize shm_size_for(std::uint64_t free_bytes);

// Registers a generated type with no type information announced: Fast DDS 2.9 writers
// that send TypeObject/TypeInformation are rejected by Cyclone DDS 0.10.
void register_type(eprosima::fastdds::dds::DomainParticipant& participant,
                   eprosima::fastdds::dds::TypeSupport type);

}  // namespace cell_dds
