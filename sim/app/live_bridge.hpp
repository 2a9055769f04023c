// `cellsim bridge`: the cell's topics served live to Foxglove (foxglove/bridge.hpp) until
// SIGINT, SIGTERM or SIGHUP.
#pragma once

#include <string>

#include "dds/participant.hpp"

namespace cellsim {

struct BridgeOptions {
  int domain_id = 0;
  cell_dds::Discovery discovery;
  cell_dds::Security security;
  std::string ns;       // the cell's ROS 2 namespace (--namespace)
  int port = 8765;      // 0: a free port
  std::string address = "127.0.0.1";  // foxglove::ServerOptions::address
  double seconds = 0;   // stop after this long (0: until a signal)
};

int run_bridge(const BridgeOptions& options);

}  // namespace cellsim
