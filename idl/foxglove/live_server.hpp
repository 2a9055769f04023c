// A Foxglove WebSocket server (protocol foxglove.websocket.v1, as foxglove_bridge speaks it):
// Foxglove, or any client of the protocol, connects to ws://127.0.0.1:PORT, is told the
// channels (each a ROS 2 topic: CDR messages, ros2msg schemas), subscribes to some and
// receives their messages as they come. Loopback only: the cell's traffic stays on the machine.
//
// Every client is untrusted: its handshake is bounded (8 KiB), its frames masked, whole and
// small (64 KiB), its subscriptions counted (64), its JSON checked field by field; a client
// that breaks the protocol is told why and closed, the others go on. A slow client loses
// messages (its queue is bounded in bytes), never the cell its time.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace foxglove {

// One channel: a topic with CDR messages of a ROS 2 type, its schema in ros2msg.
struct Channel {
  std::string topic;        // "/camera/image_raw"
  std::string schema_name;  // "sensor_msgs/msg/Image"
  std::string schema;       // its ros2msg definition, the types it uses appended
};

struct ServerOptions {
  // an IPv4 address of this machine, as digits (a name is never looked up): loopback by
  // default, the cell's traffic staying on the machine; another address is the user's choice
  std::string address = "127.0.0.1";
  int port = 8765;  // 0: a free port, port() says which
  std::size_t max_clients = 8;
  std::size_t max_queued_bytes = 64u << 20;  // per client: past it, its messages are dropped
  std::size_t max_subscriptions = 64;         // per client
};

struct ServerStats {
  std::size_t clients = 0;     // connected now, handshake done
  std::uint64_t sent = 0;      // messages queued to clients
  std::uint64_t dropped = 0;   // messages a full queue did not take
  std::uint64_t refused = 0;   // connections refused or closed for a protocol error
};

class LiveServer {
 public:
  // Listens on options.address:options.port; throws std::runtime_error (one line naming the
  // address) when it cannot. The channels' ids are their index + 1.
  LiveServer(ServerOptions options, std::string name, std::vector<Channel> channels);
  ~LiveServer();
  LiveServer(const LiveServer&) = delete;
  LiveServer& operator=(const LiveServer&) = delete;

  int port() const { return port_; }
  // "ws://127.0.0.1:8765": what a viewer opens
  std::string url() const { return "ws://" + options_.address + ":" + std::to_string(port_); }
  // whether any client subscribes to channel `index` (to skip serialising what nobody reads)
  bool subscribed(std::size_t index) const;
  // One message of channel `index`, logged at `log_ns`, to every client subscribed to it.
  // Thread-safe; never waits for a client.
  void publish(std::size_t index, std::uint64_t log_ns, const std::uint8_t* data, std::size_t n);
  ServerStats stats() const;

 private:
  struct Client;
  void run();
  void accept_clients();
  void serve(Client& c, bool readable, bool writable);
  void on_handshake(Client& c);
  void on_text(Client& c, const std::string& text);
  void subscribe(Client& c, const void* json);
  void status(Client& c, int level, const std::string& message);
  void close_with(Client& c, std::uint16_t code, const std::string& why);

  ServerOptions options_;
  std::string name_;
  std::vector<Channel> channels_;
  int listen_fd_ = -1, wake_fd_ = -1, port_ = 0;
  mutable std::mutex m_;
  std::vector<std::unique_ptr<Client>> clients_;
  std::vector<int> subscribers_;  // per channel: how many subscriptions
  ServerStats stats_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace foxglove
