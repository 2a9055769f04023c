#include "dds/participant.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <fastdds/dds/log/Log.hpp>
#include <mutex>
#include <optional>
#include <set>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>
#include <fastrtps/xmlparser/XMLProfileManager.h>
#include <stdexcept>

namespace cell_dds {

using namespace eprosima::fastdds::dds;

namespace {
// Text from the environment or a command line, safe for a one-line message.
std::string config_printable(const std::string& v) {
  std::string out;
  for (char ch : v.substr(0, 60)) out += (ch >= 0x20 && ch < 0x7f) ? ch : '?';
  return v.size() > 60 ? out + "..." : out;
}

// A domain id as text: a whole number in [0, kMaxDomainId], or nullopt.
std::optional<int> parse_domain(const std::string& text) {
  if (text.empty() || text.size() > 6 || text.find_first_not_of("0123456789") != std::string::npos) return std::nullopt;
  const long v = std::strtol(text.c_str(), nullptr, 10);
  if (v > kMaxDomainId) return std::nullopt;
  return static_cast<int>(v);
}
const std::string kDomainRange = "a whole number from 0 to " + std::to_string(kMaxDomainId) +
                                 " (above, the RTPS ports of the participants this cell reaches pass 65535)";
}  // namespace

int domain_id_from_env(int fallback) {
  const char* env = std::getenv("ROS_DOMAIN_ID");
  if (env == nullptr || *env == '\0') return fallback;
  const auto d = parse_domain(env);
  if (!d) throw std::runtime_error("ROS_DOMAIN_ID='" + config_printable(env) + "' is not a domain id: " + kDomainRange);
  return *d;
}

int domain_id_from(const std::string& flag) {
  if (flag.empty()) return domain_id_from_env(0);
  const auto d = parse_domain(flag);
  if (!d) throw std::runtime_error("--domain '" + config_printable(flag) + "' is not a domain id: " + kDomainRange);
  return *d;
}

const char* to_string(DiscoveryRange r) {
  switch (r) {
    case DiscoveryRange::kLocalhost: return "LOCALHOST";
    case DiscoveryRange::kSubnet: return "SUBNET";
    case DiscoveryRange::kOff: return "OFF";
  }
  return "?";
}

Discovery parse_discovery(const char* range, const char* peers, const char* localhost_only) {
  Discovery d;
  const auto shown = [](const std::string& v) { return v.size() > 60 ? v.substr(0, 60) + "..." : v; };
  if (range && *range) {
    const std::string r = range;
    if (r == "LOCALHOST") d.range = DiscoveryRange::kLocalhost;
    else if (r == "SUBNET" || r == "SYSTEM_DEFAULT") d.range = DiscoveryRange::kSubnet;
    else if (r == "OFF") d.range = DiscoveryRange::kOff;
    else
      throw std::invalid_argument("ROS_AUTOMATIC_DISCOVERY_RANGE='" + shown(r) +
                                  "': expected LOCALHOST, SUBNET, OFF or SYSTEM_DEFAULT");
  }
  if (localhost_only && *localhost_only) {
    const std::string v = localhost_only;
    if (v == "1") d.range = DiscoveryRange::kLocalhost;
    else if (v != "0") throw std::invalid_argument("ROS_LOCALHOST_ONLY='" + shown(v) + "': expected 0 or 1");
  }
  if (peers && *peers) {
    const std::string list = peers;
    if (list.size() > 4096) throw std::invalid_argument("ROS_STATIC_PEERS: longer than 4096 characters");
    for (std::size_t a = 0, b; a <= list.size(); a = b + 1) {
      b = list.find(';', a);
      if (b == std::string::npos) b = list.size();
      std::string peer = list.substr(a, b - a);
      while (!peer.empty() && peer.front() == ' ') peer.erase(peer.begin());
      while (!peer.empty() && peer.back() == ' ') peer.pop_back();
      if (peer.empty()) continue;
      in_addr addr{};
      if (inet_pton(AF_INET, peer.c_str(), &addr) != 1)
        throw std::invalid_argument("ROS_STATIC_PEERS: '" + shown(peer) + "' is not an IPv4 address");
      // a peer is one host: a multicast group, the broadcast address or 0.0.0.0 would send
      // discovery onto every network the machine is on (issue 18, item 13)
      const std::uint32_t a4 = ntohl(addr.s_addr);
      if ((a4 >> 28) == 0xE || a4 == 0xFFFFFFFFu || a4 == 0)
        throw std::invalid_argument("ROS_STATIC_PEERS: '" + shown(peer) +
                                    "' is not a unicast address (multicast, broadcast and 0.0.0.0 are refused: a peer "
                                    "is one host)");
      if (d.static_peers.size() >= 64) throw std::invalid_argument("ROS_STATIC_PEERS: more than 64 peers");
      d.static_peers.push_back(peer);
    }
  }
  return d;
}

void check_discovery_servers(const char* value) {
  if (!value || !*value) return;
  const std::string list = value;
  const auto bad = [&](const std::string& entry, const std::string& why) {
    return std::invalid_argument("ROS_DISCOVERY_SERVER='" + config_printable(list) + "': '" + config_printable(entry) +
                                 "' " + why);
  };
  if (list.size() > 4096) throw bad(list.substr(0, 20), "and the rest: longer than 4096 characters");
  int servers = 0;
  for (std::size_t a = 0, b; a <= list.size(); a = b + 1) {
    b = list.find(';', a);
    if (b == std::string::npos) b = list.size();
    const std::string entry = list.substr(a, b - a);
    if (entry.empty()) continue;  // an empty entry skips a server id, as Fast DDS reads it
    const std::size_t colon = entry.rfind(':');
    const std::string host = colon == std::string::npos ? entry : entry.substr(0, colon);
    if (colon != std::string::npos) {
      const std::string port = entry.substr(colon + 1);
      if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
          std::stol(port) < 1 || std::stol(port) > 65535)
        throw bad(entry, "has no port from 1 to 65535 after its ':'");
    }
    in_addr addr{};
    // digits and dots alone are an address or nothing: "999.999.999.999" is no host name
    const bool numeric = !host.empty() && host.find_first_not_of("0123456789.") == std::string::npos;
    if (inet_pton(AF_INET, host.c_str(), &addr) == 1) {
      const std::uint32_t a4 = ntohl(addr.s_addr);
      if ((a4 >> 28) == 0xE || a4 == 0xFFFFFFFFu || a4 == 0) throw bad(entry, "is not a unicast address");
    } else if (numeric) {
      throw bad(entry, "is not an IPv4 address (four numbers from 0 to 255)");
    } else if (host.empty() || host.size() > 253 ||
               host.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789.-") !=
                   std::string::npos) {
      throw bad(entry, "is not ADDRESS[:PORT] (an IPv4 address or a host name)");
    }
    if (++servers > 64) throw bad(entry, "is past the 64th server");
  }
  if (servers == 0) throw bad(list.substr(0, 20), "names no server (unset it for no discovery server)");
}

Discovery discovery_from_env() {
  // Fast DDS reads ROS_DISCOVERY_SERVER itself and skips what it cannot parse without a word:
  // it is checked here, so a typo is an error and not a cell that silently finds nobody
  check_discovery_servers(std::getenv("ROS_DISCOVERY_SERVER"));
  return parse_discovery(std::getenv("ROS_AUTOMATIC_DISCOVERY_RANGE"), std::getenv("ROS_STATIC_PEERS"),
                         std::getenv("ROS_LOCALHOST_ONLY"));
}

Discovery discovery_from(const std::string& range_flag, const std::string& peers_flag) {
  Discovery d = discovery_from_env();
  const auto renamed = [](const std::invalid_argument& e, const std::string& var, const std::string& flag) {
    std::string m = e.what();
    const auto at = m.find(var);
    if (at != std::string::npos) m.replace(at, var.size(), flag);
    return std::invalid_argument(m);
  };
  if (!range_flag.empty()) {
    try {
      d.range = parse_discovery(range_flag.c_str(), nullptr, nullptr).range;
    } catch (const std::invalid_argument& e) {
      throw renamed(e, "ROS_AUTOMATIC_DISCOVERY_RANGE", "--discovery-range");
    }
  }
  if (!peers_flag.empty()) {
    try {
      d.static_peers = parse_discovery(nullptr, peers_flag.c_str(), nullptr).static_peers;
    } catch (const std::invalid_argument& e) {
      throw renamed(e, "ROS_STATIC_PEERS", "--static-peers");
    }
  }
  return d;
}

Security security_from_env() {
  Security s;
  const char* enable = std::getenv("ROS_SECURITY_ENABLE");
  if (enable && *enable) {
    const std::string v = enable;
    if (v == "true") s.enabled = true;
    else if (v != "false") throw std::invalid_argument("ROS_SECURITY_ENABLE='" + v.substr(0, 40) + "': expected true or false");
  }
  const char* strategy = std::getenv("ROS_SECURITY_STRATEGY");
  if (strategy && *strategy) {
    const std::string v = strategy;
    if (v == "Enforce") s.enforce = true;
    else if (v == "Permissive") s.enforce = false;
    else throw std::invalid_argument("ROS_SECURITY_STRATEGY='" + v.substr(0, 40) + "': expected Enforce or Permissive");
  }
  if (const char* k = std::getenv("ROS_SECURITY_KEYSTORE")) s.keystore = k;
  if (const char* e = std::getenv("ROS_SECURITY_ENCLAVE_OVERRIDE")) s.enclave_override = e;
  if (s.enabled && s.keystore.empty())
    throw std::invalid_argument("ROS_SECURITY_ENABLE=true but ROS_SECURITY_KEYSTORE is not set");
  return s;
}

namespace {

// Fast DDS's log, as one plain line per entry ("fastdds: ERROR category: message"); while a
// participant is being created its errors are held instead, so that a refused participant
// (a certificate that does not verify, has expired...) is reported in one line with the reason.
class OneLineLog : public eprosima::fastdds::dds::LogConsumer {
 public:
  void Consume(const eprosima::fastdds::dds::Log::Entry& e) override {
    std::lock_guard<std::mutex> lock(m_);
    std::string message = e.message;
    for (char& c : message)
      if (c == '\n' || c == '\r') c = ' ';
    const char* kind = e.kind == eprosima::fastdds::dds::Log::Kind::Error ? "ERROR" : "warning";
    const std::string category = e.context.category ? e.context.category : "";
    if (holding_) {
      if (held_.empty() && e.kind == eprosima::fastdds::dds::Log::Kind::Error && !message.empty()) held_ = category + ": " + message;
      return;
    }
    std::fprintf(stderr, "fastdds: %s %s: %s\n", kind, category.c_str(), message.c_str());
  }
  void hold(bool on) {
    std::lock_guard<std::mutex> lock(m_);
    holding_ = on;
    if (on) held_.clear();
  }
  std::string held() {
    std::lock_guard<std::mutex> lock(m_);
    return held_;
  }

 private:
  std::mutex m_;
  bool holding_ = false;
  std::string held_;
};

OneLineLog& one_line_log() {
  static OneLineLog* log = [] {
    auto consumer = std::make_unique<OneLineLog>();
    OneLineLog* raw = consumer.get();
    eprosima::fastdds::dds::Log::ClearConsumers();
    eprosima::fastdds::dds::Log::RegisterConsumer(std::move(consumer));
    return raw;
  }();
  return *log;
}

// The enclave's six files as Fast DDS's built-in plugins take them; false (Permissive) when
// the enclave is missing, throws naming the file otherwise.
bool add_security(DomainParticipantQos& qos, const Security& sec, const std::string& enclave_name) {
  std::string enclave = sec.enclave_override.empty() ? enclave_name : sec.enclave_override;
  while (!enclave.empty() && enclave.front() == '/') enclave.erase(enclave.begin());
  // an enclave is a ROS 2 name: letters, digits, '_' and '/' (never printed raw: it may come
  // from ROS_SECURITY_ENCLAVE_OVERRIDE with control bytes in it)
  if (enclave.empty() || enclave.size() > 255 || enclave.find("..") != std::string::npos ||
      enclave.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_/") != std::string::npos)
    throw std::invalid_argument("security enclave '" + config_printable(enclave) +
                                "': not an enclave name (letters, digits, '_' and '/'; ROS_SECURITY_ENCLAVE_OVERRIDE)");
  const std::filesystem::path dir = std::filesystem::path(sec.keystore) / "enclaves" / enclave;
  const char* files[] = {"identity_ca.cert.pem", "cert.pem", "key.pem", "permissions_ca.cert.pem", "governance.p7s",
                         "permissions.p7s"};
  for (const char* f : files) {
    std::error_code ec;
    if (std::filesystem::is_regular_file(dir / f, ec) && access((dir / f).c_str(), R_OK) == 0) continue;
    if (!sec.enforce) {
      std::fprintf(stderr, "%s: missing: running WITHOUT security (ROS_SECURITY_STRATEGY=Permissive)\n",
                   (dir / f).c_str());
      return false;
    }
    throw std::invalid_argument((dir / f).string() + ": missing or unreadable (ROS_SECURITY_STRATEGY=Enforce)");
  }
  auto& props = qos.properties().properties();
  const auto file = [&](const char* f) { return "file://" + std::filesystem::absolute(dir / f).string(); };
  props.emplace_back("dds.sec.auth.plugin", "builtin.PKI-DH");
  props.emplace_back("dds.sec.auth.builtin.PKI-DH.identity_ca", file("identity_ca.cert.pem"));
  props.emplace_back("dds.sec.auth.builtin.PKI-DH.identity_certificate", file("cert.pem"));
  props.emplace_back("dds.sec.auth.builtin.PKI-DH.private_key", file("key.pem"));
  props.emplace_back("dds.sec.access.plugin", "builtin.Access-Permissions");
  props.emplace_back("dds.sec.access.builtin.Access-Permissions.permissions_ca", file("permissions_ca.cert.pem"));
  props.emplace_back("dds.sec.access.builtin.Access-Permissions.governance", file("governance.p7s"));
  props.emplace_back("dds.sec.access.builtin.Access-Permissions.permissions", file("permissions.p7s"));
  props.emplace_back("dds.sec.crypto.plugin", "builtin.AES-GCM-GMAC");
  return true;
}
}  // namespace

void ParticipantDeleter::operator()(DomainParticipant* p) const {
  if (p == nullptr) return;
  p->delete_contained_entities();
  DomainParticipantFactory::get_instance()->delete_participant(p);
}

namespace {

// Fast DDS 2.9's shared-memory transport and processes that die by SIGKILL: the dead
// listener's port (/dev/shm/fastrtps_port<N>) stays mapped by the live senders that cached it,
// and a new participant that takes the same participant id (the lowest free one, so exactly
// the dead one's) opens that port and receives nothing, ever (eProsima/Fast-DDS#2811, #4728;
// seen as a restarted servo that never answered). So the participant id is chosen here: the
// lowest whose UDP ports are free and whose shared-memory ports do not exist. Port files no
// process maps any more are removed first, so ids come back once nobody can hold them.
constexpr const char* kShmDir = "/dev/shm/";
constexpr int kMaxParticipantId = 120;

// Shared memory (Fast DDS 2.9). A sender keeps each buffer it queued into a reader's port until
// that reader takes it; a reader killed with SIGKILL never does, and the sender reclaims such
// buffers only when its segment runs short of bytes. In our former 8 MB segment the dead
// reader's buffers cut the free space into holes smaller than one 64 KB message while the total
// free stayed above it: every image fragment failed to allocate (thousands of overflows, logged
// at Info level only) and a restarted servo heard no image again (CI, stop 38). A segment holds
// at most kShmBuffers buffers (Fast DDS reclaims the oldest when all are taken), so with room
// for twice that many messages and one more, some hole always fits a message, whatever the
// others hold. Fewer buffers would shrink the segment but let a starved reader's buffers be
// reclaimed before it took them (64 lost a test watcher's last pose under load).
constexpr std::uint32_t kShmBuffers = 512;               // Fast DDS's own port depth
constexpr std::uint32_t kShmMaxMessageBytes = 65'536;    // a UDP datagram: Fast DDS's message cap
constexpr std::uint32_t kShmSlackBytes = 1u << 20;       // the allocator's block headers and alignment
constexpr std::uint32_t shm_segment_bytes(std::uint32_t buffers) {
  return (2 * buffers + 1) * kShmMaxMessageBytes + kShmSlackBytes;
}
constexpr std::uint32_t kShmSegmentBytes = shm_segment_bytes(kShmBuffers);  // 65 MB
// what this machine's /dev/shm allows (shm_size_for)
ShmSize shm_size() {
  struct statvfs v {};
  if (statvfs(kShmDir, &v) != 0) return {kShmSegmentBytes, kShmBuffers};
  return shm_size_for(static_cast<std::uint64_t>(v.f_bavail) * v.f_frsize);
}

// Every process with a port open runs a watchdog that calls the port dead when its listener has
// not checked in for this long; a port called dead is removed and made anew, and a sender still
// holding the old one sends into a port nobody reads. Fast DDS's 1 s is shorter than a starved
// process's pause on a loaded 2-core machine (a live cellsim's own port was removed so).
constexpr std::uint32_t kShmHealthyCheckMs = 10'000;

int unicast_port(int domain, int id, int offset) { return 7400 + 250 * domain + offset + 2 * id; }

bool udp_port_free(int port) {
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  if (fd < 0) return false;
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const bool ok = bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  close(fd);
  return ok;
}

bool shm_port_exists(int port) {
  std::error_code ec;
  return std::filesystem::exists(kShmDir + std::string("fastrtps_port") + std::to_string(port), ec);
}

// Fast DDS's shared-memory files: a port ("fastrtps_port7411") or a sender's segment
// ("fastrtps_" and 16 hex digits); not their "_el" locks or "_mutex" semaphores.
bool is_fastdds_shm_file(const std::string& name) {
  const std::string prefix = "fastrtps_";
  if (name.rfind(prefix, 0) != 0) return false;
  const std::string rest = name.substr(prefix.size());
  if (rest.rfind("port", 0) == 0)
    return rest.size() > 4 && rest.find_first_not_of("0123456789", 4) == std::string::npos;
  return rest.size() == 16 && rest.find_first_not_of("0123456789abcdef") == std::string::npos;
}

// Once per process, before its first participant.
void remove_orphaned_shm_files_once() {
  static std::once_flag once;
  std::call_once(once, [] { remove_orphaned_shm_files(kShmDir, std::chrono::seconds(60)); });
}

// The lowest participant id at or after `from` that is free on UDP and in shared memory.
int free_participant_id(int domain, int from) {
  for (int id = from; id < kMaxParticipantId; ++id) {
    const int meta = unicast_port(domain, id, 10), user = unicast_port(domain, id, 11);
    if (user > 65535) break;
    if (shm_port_exists(meta) || shm_port_exists(user)) continue;
    if (!udp_port_free(meta) || !udp_port_free(user)) continue;
    // two of our processes starting at once would both see the id free: the first to lock
    // it takes it (the lock lives as long as the process; the next participant takes the next id)
    const std::string lock = "/tmp/cell_dds_participant_" + std::to_string(domain) + "_" + std::to_string(id) + ".lock";
    const int fd = open(lock.c_str(), O_CREAT | O_RDWR | O_CLOEXEC, 0666);
    if (fd < 0) return id;  // no /tmp: the port checks alone
    if (flock(fd, LOCK_EX | LOCK_NB) == 0) return id;
    close(fd);
  }
  return -1;
}

// The transports (UDPv4, loopback only unless the range or a static peer asks for more; shared
// memory for large frames) and the peers discovery announces to.
void configure_network(DomainParticipantQos& qos, const ParticipantOptions& o) {
  const Discovery& d = o.discovery;
  // nothing leaves the machine unless the range or a static peer asks for it
  const bool loopback_only = d.range != DiscoveryRange::kSubnet && d.static_peers.empty();
  const auto peer_locator = [](const std::string& address) {
    eprosima::fastrtps::rtps::Locator_t l;
    l.kind = LOCATOR_KIND_UDPv4;
    eprosima::fastrtps::rtps::IPLocator::setIPv4(l, address);
    return l;
  };
  qos.transport().use_builtin_transports = false;
  auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
  // LOCALHOST: nothing leaves the machine; the other ranges use every interface
  if (loopback_only) udp->interfaceWhiteList.emplace_back("127.0.0.1");
  // the initial peers are tried at this many participant ids: ids skipped for dead
  // processes' ports (below) must stay within reach
  udp->maxInitialPeersRange = 64;
  qos.transport().user_transports.push_back(udp);
  // large frames between processes of one host go through shared memory
  auto shm = std::make_shared<eprosima::fastdds::rtps::SharedMemTransportDescriptor>();
  const ShmSize size = shm_size();
  shm->segment_size(size.segment_bytes);
  shm->port_queue_capacity(size.buffers);
  shm->healthy_check_timeout_ms(kShmHealthyCheckMs);
  qos.transport().user_transports.push_back(shm);
  auto& peers = qos.wire_protocol().builtin.initialPeersList;
  if (d.range == DiscoveryRange::kLocalhost) peers.push_back(peer_locator("127.0.0.1"));
  if (d.range == DiscoveryRange::kSubnet) {
    // an explicit initial peers list replaces Fast DDS's default multicast announcement:
    // put it back, so SUBNET still discovers by multicast
    eprosima::fastrtps::rtps::Locator_t m = peer_locator("239.255.0.1");
    m.port = static_cast<std::uint32_t>(7400 + 250 * o.domain_id);
    peers.push_back(m);
  }
  // LOCALHOST and OFF announce to these peers only, never to a multicast group (multicast
  // sent by others, e.g. a default-configured client on the same network, is still heard)
  for (const auto& a : d.static_peers) peers.push_back(peer_locator(a));
  if (peers.empty()) {
    // OFF with no static peer: an empty list would make Fast DDS announce to its default
    // multicast group; one loopback port nobody listens on keeps the participant silent
    eprosima::fastrtps::rtps::Locator_t nowhere = peer_locator("127.0.0.1");
    nowhere.port = 9;  // discard
    peers.push_back(nowhere);
  }
}

// A participant on the first participant id free on this host (flock-claimed), or on Fast
// DDS's own choice when none is; null when Fast DDS refuses.
DomainParticipant* create_on_free_id(DomainParticipantQos& qos, int domain_id) {
  DomainParticipant* p = nullptr;
  {
    remove_orphaned_shm_files_once();
    // another process may take the same id between the check and the bind: try the next
    for (int attempt = 0, id = 0; attempt < 5 && p == nullptr; ++attempt, ++id) {
      id = free_participant_id(domain_id, id);
      if (id < 0) break;
      qos.wire_protocol().participant_id = id;
      p = DomainParticipantFactory::get_instance()->create_participant(domain_id, qos);
    }
  }
  if (p == nullptr) {
    qos.wire_protocol().participant_id = -1;  // Fast DDS's own choice
    p = DomainParticipantFactory::get_instance()->create_participant(domain_id, qos);
  }
  return p;
}

}  // namespace

ParticipantPtr make_participant(const ParticipantOptions& o) {
  if (!o.intraprocess) {
    // library-wide: must be set before the first participant is created
    eprosima::fastrtps::LibrarySettingsAttributes lib;
    lib.intraprocess_delivery = eprosima::fastrtps::INTRAPROCESS_OFF;
    eprosima::fastrtps::xmlparser::XMLProfileManager::library_settings(lib);
  }
  DomainParticipantQos qos = PARTICIPANT_QOS_DEFAULT;
  qos.name(o.name);
  configure_network(qos, o);
  const bool secured = o.security.enabled && add_security(qos, o.security, o.enclave.empty() ? o.name : o.enclave);
  OneLineLog& log = one_line_log();
  log.hold(true);
  DomainParticipant* p = create_on_free_id(qos, o.domain_id);
  eprosima::fastdds::dds::Log::Flush();
  const std::string reason = log.held();
  log.hold(false);
  if (p == nullptr)
    throw std::runtime_error("cannot create a DDS participant '" + o.name + "' on domain " + std::to_string(o.domain_id) +
                             (reason.empty() ? std::string() : ": " + reason) +
                             (secured ? " (check the enclave: a certificate or permissions that do not verify against "
                                        "the keystore's CA, or have expired)"
                                      : ""));
  // a secured participant says so once: a run that is secured looks like any other otherwise
  if (secured)
    std::printf("%s: DDS-Security on: enclave /%s, %s, keystore %s\n", o.name.c_str(),
                 (o.security.enclave_override.empty() ? (o.enclave.empty() ? o.name : o.enclave) : o.security.enclave_override).c_str(),
                 o.security.enforce ? "Enforce" : "Permissive", o.security.keystore.c_str());
  if (secured) std::fflush(stdout);
  return ParticipantPtr(p);
}

void register_type(DomainParticipant& participant, TypeSupport type) {
  type->auto_fill_type_information(false);
  type->auto_fill_type_object(false);
  if (type.register_type(&participant) != ReturnCode_t::RETCODE_OK)
    throw std::runtime_error("cannot register DDS type " + type.get_type_name());
}

namespace {

// The names under `dir` that a live process maps or holds open (/proc/PID/maps and the links
// in /proc/PID/fd): a file in use is never an orphan, whatever its lock says.
std::set<std::string> files_in_use(const std::filesystem::path& dir) {
  std::set<std::string> used;
  const std::string prefix = dir.string() + (dir.string().empty() || dir.string().back() == '/' ? "" : "/");
  const auto note = [&](const std::string& path) {
    if (path.rfind(prefix, 0) != 0) return;
    std::string name = path.substr(prefix.size());
    if (const auto sp = name.find(" (deleted)"); sp != std::string::npos) name.resize(sp);
    if (name.find('/') == std::string::npos) used.insert(name);
  };
  std::error_code ec;
  for (const auto& proc : std::filesystem::directory_iterator("/proc", ec)) {
    std::ifstream maps(proc.path() / "maps");
    std::string line;
    while (std::getline(maps, line))
      if (const auto at = line.find(prefix); at != std::string::npos) note(line.substr(at));
    std::error_code fd_ec;
    for (const auto& fd : std::filesystem::directory_iterator(proc.path() / "fd", fd_ec)) {
      std::error_code link_ec;
      note(std::filesystem::read_symlink(fd.path(), link_ec).string());
    }
  }
  return used;
}

// This user's regular file (not a link, a folder, a FIFO or another user's), old enough.
bool ours_and_regular(const std::filesystem::path& p, std::chrono::seconds min_age) {
  struct stat st {};
  if (lstat(p.c_str(), &st) != 0 || !S_ISREG(st.st_mode) || st.st_uid != geteuid()) return false;
  return std::chrono::system_clock::now() - std::chrono::system_clock::from_time_t(st.st_mtime) >= min_age;
}

// The owner of a Fast DDS file holds flock on its "<name>_el" while it lives (Fast DDS's
// RobustExclusiveLock; an fcntl lock test would not see it). Free: the lock is this user's
// regular file (a link may lead to a lock some process holds, a FIFO would hang the open) and
// flock can take it now.
bool lock_free(const std::filesystem::path& el) {
  if (!ours_and_regular(el, std::chrono::seconds(0))) return false;
  const int fd = open(el.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK);
  if (fd < 0) return false;
  struct stat st {};
  const bool free = fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && flock(fd, LOCK_EX | LOCK_NB) == 0;
  close(fd);  // releases the lock if this test took it
  return free;
}

bool is_datasharing_file(const std::string& name) {
  const std::string prefix = "fast_datasharing_";
  return name.size() > prefix.size() && name.rfind(prefix, 0) == 0 &&
         name.find_first_not_of("0123456789abcdef._", prefix.size()) == std::string::npos;
}

}  // namespace

std::vector<std::string> remove_orphaned_shm_files(const std::filesystem::path& dir, std::chrono::seconds min_age) {
  std::vector<std::string> removed;
  const std::set<std::string> used = files_in_use(dir);
  std::error_code ec;
  for (const auto& f : std::filesystem::directory_iterator(dir, ec)) {
    const std::string name = f.path().filename().string();
    const bool port_or_segment = is_fastdds_shm_file(name), datasharing = is_datasharing_file(name);
    if ((!port_or_segment && !datasharing) || used.count(name) || !ours_and_regular(f.path(), min_age)) continue;
    // a data-sharing pool has no lock: that no process maps or holds it is what makes it an orphan
    const std::filesystem::path el = f.path().string() + "_el";
    if (port_or_segment && (used.count(name + "_el") || !lock_free(el))) continue;
    std::error_code rm_ec;
    std::filesystem::remove(f.path(), rm_ec);
    if (port_or_segment) std::filesystem::remove(el, rm_ec);
    // the port's semaphore, when it is this user's regular file (a folder planted there stays)
    const std::filesystem::path sem = dir / ("sem." + name + "_mutex");
    if (port_or_segment && ours_and_regular(sem, std::chrono::seconds(0))) std::filesystem::remove(sem, rm_ec);
    removed.push_back(name);
  }
  return removed;
}

ShmSize shm_size_for(std::uint64_t free_bytes) {
  const std::uint64_t share = free_bytes / 8;
  if (share >= kShmSegmentBytes) return {kShmSegmentBytes, kShmBuffers};
  const std::uint64_t messages = share > kShmSlackBytes ? (share - kShmSlackBytes) / kShmMaxMessageBytes : 0;
  const std::uint64_t fit = messages > 0 ? (messages - 1) / 2 : 0;  // 2 x fit + 1 messages
  const std::uint32_t buffers = static_cast<std::uint32_t>(std::max<std::uint64_t>(fit, 16));
  return {shm_segment_bytes(buffers), buffers};
}

}  // namespace cell_dds
