#include "sim/app/live_bridge.hpp"

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <thread>

#include "dds/cli_flags.hpp"
#include "foxglove/bridge.hpp"

namespace cellsim {

namespace {
std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }
}  // namespace

int run_bridge(const BridgeOptions& o) {
  auto participant = cell_dds::make_participant(cell_dds::participant_options(o, "cellsim_bridge", "cellsim_bridge"));
  foxglove::ServerOptions server;
  server.port = o.port;
  server.address = o.address;
  foxglove::Bridge bridge(*participant, o.ns, server);
  for (const int sig : {SIGINT, SIGTERM, SIGHUP}) std::signal(sig, on_signal);
  // the address a viewer opens: Foxglove, "Open connection", Foxglove WebSocket
  std::printf("cellsim bridge: %s (foxglove.websocket.v1), %zu topics%s%s\n", bridge.url().c_str(),
              bridge.channels(), o.ns.empty() ? "" : " under /", o.ns.c_str());
  std::fflush(stdout);
  const auto start = std::chrono::steady_clock::now();
  while (!g_stop && (o.seconds <= 0 || std::chrono::steady_clock::now() - start < std::chrono::duration<double>(o.seconds)))
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const foxglove::ServerStats s = bridge.stats();
  std::printf("cellsim bridge: stopped; %llu messages sent, %llu dropped (a viewer too slow), %llu connections refused\n",
              static_cast<unsigned long long>(s.sent), static_cast<unsigned long long>(s.dropped),
              static_cast<unsigned long long>(s.refused));
  return 0;
}

}  // namespace cellsim
