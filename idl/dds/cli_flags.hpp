// The DDS flags every service and tool of the cell takes, declared once (issue 20: they were
// written out three times, in `cellsim serve`, `servo run` and `servo view`), and how they map
// onto its participant: the domain, the discovery range and static peers, the namespace, and
// DDS-Security from the environment. For the apps (CLI11); the library does not need it.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "dds/participant.hpp"
#include "dds/topics.hpp"

namespace cell_dds {

struct DdsFlags {
  std::string domain, discovery_range, static_peers, ns;

  void add_to(CLI::App& app) {
    app.add_option("--domain", domain, "DDS domain id (default: $ROS_DOMAIN_ID or 0)");
    app.add_option("--discovery-range", discovery_range,
                   "LOCALHOST | SUBNET | OFF (default: $ROS_AUTOMATIC_DISCOVERY_RANGE, or LOCALHOST)");
    app.add_option("--static-peers", static_peers,
                   "semicolon-separated IPv4 addresses to discover by unicast (default: $ROS_STATIC_PEERS)");
    app.add_option("--namespace", ns,
                   "the cell's ROS 2 namespace: its topics become rt/NAME/... (several cells on one domain)");
  }

  // Fills the options' domain_id, discovery, ns and security. Throws std::invalid_argument (one
  // line naming the flag or variable) for a bad value.
  template <class Options>
  void apply_to(Options& o) const {
    o.domain_id = domain_id_from(domain);
    o.discovery = discovery_from(discovery_range, static_peers);
    o.ns = checked_namespace(ns);
    o.security = security_from_env();
  }
};

// The participant of a service or tool: the options DdsFlags filled, its name, and its SROS2
// enclave laid out by node path (/NS/LEAF under --namespace NS, as bin/keystore --namespace does).
template <class Options>
ParticipantOptions participant_options(const Options& o, const std::string& name, const std::string& enclave_leaf) {
  ParticipantOptions po;
  po.domain_id = o.domain_id;
  po.name = name;
  po.discovery = o.discovery;
  po.security = o.security;
  po.enclave = o.ns.empty() ? enclave_leaf : o.ns + "/" + enclave_leaf;
  return po;
}

}  // namespace cell_dds
