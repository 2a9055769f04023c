#include "foxglove/live_server.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <deque>
#include <map>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "foxglove/websocket.hpp"

namespace foxglove {

// a connection has this long to complete its handshake: one that never does holds no slot
constexpr std::chrono::seconds kHandshakeDeadline{10};

struct LiveServer::Client {
  int fd = -1;
  std::chrono::steady_clock::time_point connected = std::chrono::steady_clock::now();
  std::string request;  // the opening handshake, until its blank line
  bool open = false;    // handshake done
  bool closing = false;  // close once the queue is written
  FrameReader reader;
  std::map<std::uint32_t, std::uint32_t> subscriptions;  // subscription id -> channel id
  std::deque<std::string> out;
  std::size_t out_bytes = 0, out_offset = 0;
  void queue(std::string bytes) {
    out_bytes += bytes.size();
    out.push_back(std::move(bytes));
  }
};

namespace {

// rouses the server's thread from its poll
void wake(int fd) {
  const std::uint64_t one = 1;
  if (fd >= 0 && ::write(fd, &one, sizeof one) < 0) {
    // the counter is full: the thread is already due to wake
  }
}

void put_le(std::string& s, std::uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) s.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}

}  // namespace

LiveServer::LiveServer(ServerOptions options, std::string name, std::vector<Channel> channels)
    : options_(options), name_(std::move(name)), channels_(std::move(channels)), subscribers_(channels_.size(), 0) {
  const std::string where = options_.address + ":" + std::to_string(options_.port);
  if (options_.port < 0 || options_.port > 65535) throw std::runtime_error(where + ": not a port");
  in_addr ip{};
  if (options_.address.size() > 15 || ::inet_pton(AF_INET, options_.address.c_str(), &ip) != 1)
    throw std::runtime_error("'" + options_.address.substr(0, 40) +
                             "' is not an IPv4 address written in digits (names are not looked up)");
  listen_fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (listen_fd_ < 0) throw std::runtime_error(where + ": " + std::strerror(errno));
  const int yes = 1;
  ::setsockopt(listen_fd_, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr = ip;
  a.sin_port = htons(static_cast<std::uint16_t>(options_.port));
  socklen_t len = sizeof a;
  if (::bind(listen_fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(listen_fd_, 16) != 0 ||
      ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
    const std::string why = std::strerror(errno);
    ::close(listen_fd_);
    throw std::runtime_error(where + ": " + why);
  }
  port_ = ntohs(a.sin_port);
  wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  thread_ = std::thread([this] { run(); });
}

LiveServer::~LiveServer() {
  stop_ = true;
  wake(wake_fd_);
  if (thread_.joinable()) thread_.join();
  for (const auto& c : clients_) ::close(c->fd);
  if (wake_fd_ >= 0) ::close(wake_fd_);
  ::close(listen_fd_);
}

bool LiveServer::subscribed(std::size_t index) const {
  std::lock_guard<std::mutex> l(m_);
  return index < subscribers_.size() && subscribers_[index] > 0;
}

ServerStats LiveServer::stats() const {
  std::lock_guard<std::mutex> l(m_);
  return stats_;
}

void LiveServer::publish(std::size_t index, std::uint64_t log_ns, const std::uint8_t* data, std::size_t n) {
  const auto channel_id = static_cast<std::uint32_t>(index + 1);
  bool queued = false;
  {
    std::lock_guard<std::mutex> l(m_);
    if (index >= subscribers_.size() || subscribers_[index] == 0) return;
    for (const auto& c : clients_)
      for (const auto& [sub, ch] : c->subscriptions) {
        if (ch != channel_id || c->closing) continue;
        if (c->out_bytes + n + 27 > options_.max_queued_bytes) {
          ++stats_.dropped;
          continue;
        }
        // Message Data: opcode 0x01, the subscription id, the time, the CDR bytes
        std::string f = frame_header(Opcode::kBinary, 13 + n);
        f.push_back(1);
        put_le(f, sub, 4);
        put_le(f, log_ns, 8);
        f.append(reinterpret_cast<const char*>(data), n);
        c->queue(std::move(f));
        ++stats_.sent;
        queued = true;
      }
  }
  if (queued) wake(wake_fd_);
}

void LiveServer::run() {
  std::vector<pollfd> fds;
  while (!stop_) {
    {
      std::lock_guard<std::mutex> l(m_);
      fds.assign({{listen_fd_, POLLIN, 0}, {wake_fd_, POLLIN, 0}});
      for (const auto& c : clients_)
        fds.push_back({c->fd, static_cast<short>(POLLIN | (c->out.empty() ? 0 : POLLOUT)), 0});
    }
    if (::poll(fds.data(), fds.size(), 200) < 0 && errno != EINTR) break;
    std::uint64_t woken;
    if ((fds[1].revents & POLLIN) && ::read(wake_fd_, &woken, sizeof woken) < 0) {
      // nothing to read: another wake-up took it
    }
    std::lock_guard<std::mutex> l(m_);
    for (std::size_t i = 2; i < fds.size() && i - 2 < clients_.size(); ++i)
      if (clients_[i - 2]->fd == fds[i].fd)
        serve(*clients_[i - 2], fds[i].revents & (POLLIN | POLLHUP | POLLERR), fds[i].revents & POLLOUT);
    const auto now = std::chrono::steady_clock::now();
    for (const auto& c : clients_)
      if (c->fd >= 0 && !c->open && !c->closing && now - c->connected > kHandshakeDeadline) {
        ::close(c->fd);
        c->fd = -1;
        ++stats_.refused;
      }
    // a closed client's subscriptions go with it
    for (auto it = clients_.begin(); it != clients_.end();) {
      if ((*it)->fd >= 0) {
        ++it;
        continue;
      }
      for (const auto& [sub, ch] : (*it)->subscriptions) --subscribers_[ch - 1];
      if ((*it)->open) --stats_.clients;
      it = clients_.erase(it);
    }
    if (fds[0].revents & POLLIN) accept_clients();
  }
}

void LiveServer::accept_clients() {
  for (;;) {
    const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) return;
    if (clients_.size() >= options_.max_clients) {
      const std::string r = refusal("too many viewers (at most " + std::to_string(options_.max_clients) + ")");
      if (::send(fd, r.data(), r.size(), MSG_NOSIGNAL | MSG_DONTWAIT) < 0) {
        // the refusal is a courtesy: the connection closes either way
      }
      ::close(fd);
      ++stats_.refused;
      continue;
    }
    auto c = std::make_unique<Client>();
    c->fd = fd;
    clients_.push_back(std::move(c));
  }
}

// Reads what the client sent, writes what is queued for it; on an error or a close, its fd is
// closed and set to -1 (run() removes it).
void LiveServer::serve(Client& c, bool readable, bool writable) {
  if (readable) {
    char buf[16384];
    const ssize_t n = ::recv(c.fd, buf, sizeof buf, MSG_DONTWAIT);
    if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR)) {
      ::close(c.fd);
      c.fd = -1;
      return;
    }
    if (n > 0 && !c.open && !c.closing) {
      c.request.append(buf, static_cast<std::size_t>(n));
      if (c.request.find("\r\n\r\n") != std::string::npos || c.request.size() > kMaxHandshakeBytes) on_handshake(c);
    } else if (n > 0 && c.open && !c.closing) {
      std::vector<Frame> frames;
      const bool ok = c.reader.feed(buf, static_cast<std::size_t>(n), frames);
      for (const Frame& f : frames) {
        if (c.closing) break;
        if (f.opcode == Opcode::kText) on_text(c, f.payload);
        else if (f.opcode == Opcode::kBinary) status(c, 2, "client publishing is not supported: binary message ignored");
        else if (f.opcode == Opcode::kPing) c.queue(frame(Opcode::kPong, f.payload));
        else if (f.opcode == Opcode::kClose) close_with(c, 1000, "");
      }
      if (!ok && !c.closing) close_with(c, 1002, c.reader.error());
    }
  }
  if (writable || !c.out.empty()) {
    while (!c.out.empty()) {
      const std::string& front = c.out.front();
      const ssize_t n = ::send(c.fd, front.data() + c.out_offset, front.size() - c.out_offset, MSG_NOSIGNAL | MSG_DONTWAIT);
      if (n < 0) {
        if (errno == EAGAIN || errno == EINTR) break;
        ::close(c.fd);
        c.fd = -1;
        return;
      }
      c.out_offset += static_cast<std::size_t>(n);
      if (c.out_offset < front.size()) break;
      c.out_bytes -= front.size();
      c.out.pop_front();
      c.out_offset = 0;
    }
  }
  if (c.closing && c.out.empty()) {
    ::close(c.fd);
    c.fd = -1;
  }
}

void LiveServer::on_handshake(Client& c) {
  const Handshake h = parse_handshake(c.request);
  c.request.clear();
  c.request.shrink_to_fit();
  if (!h.error.empty()) {
    c.queue(refusal(h.error));
    c.closing = true;
    ++stats_.refused;
    return;
  }
  c.queue(handshake_reply(h.key));
  c.open = true;
  ++stats_.clients;
  nlohmann::json info{{"op", "serverInfo"}, {"name", name_}, {"capabilities", nlohmann::json::array()},
                      {"metadata", nlohmann::json::object()}};
  c.queue(frame(Opcode::kText, info.dump()));
  nlohmann::json channels = nlohmann::json::array();
  for (std::size_t i = 0; i < channels_.size(); ++i)
    channels.push_back({{"id", i + 1}, {"topic", channels_[i].topic}, {"encoding", "cdr"},
                        {"schemaName", channels_[i].schema_name}, {"schema", channels_[i].schema},
                        {"schemaEncoding", "ros2msg"}});
  c.queue(frame(Opcode::kText, nlohmann::json{{"op", "advertise"}, {"channels", channels}}.dump()));
}

void LiveServer::on_text(Client& c, const std::string& text) {
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object() || !j.contains("op") || !j["op"].is_string()) {
    status(c, 2, "not a JSON object with a string 'op': ignored");
    return;
  }
  const std::string op = j["op"].get<std::string>();
  if (op == "subscribe") {
    subscribe(c, &j);
  } else if (op == "unsubscribe") {
    const auto ids = j.find("subscriptionIds");
    if (ids == j.end() || !ids->is_array()) return status(c, 2, "unsubscribe: 'subscriptionIds' must be an array");
    for (const auto& id : *ids) {
      if (!id.is_number_unsigned() || id.get<std::uint64_t>() > 0xFFFFFFFFull) continue;
      const auto it = c.subscriptions.find(id.get<std::uint32_t>());
      if (it == c.subscriptions.end()) continue;
      --subscribers_[it->second - 1];
      c.subscriptions.erase(it);
    }
  } else {
    status(c, 1, "op '" + op.substr(0, 64) + "' is not supported by this server: ignored");
  }
}

void LiveServer::subscribe(Client& c, const void* json) {
  const nlohmann::json& j = *static_cast<const nlohmann::json*>(json);
  const auto subs = j.find("subscriptions");
  if (subs == j.end() || !subs->is_array()) return status(c, 2, "subscribe: 'subscriptions' must be an array");
  for (const auto& s : *subs) {
    if (!s.is_object() || !s.contains("id") || !s.contains("channelId") || !s["id"].is_number_unsigned() ||
        !s["channelId"].is_number_unsigned() || s["id"].get<std::uint64_t>() > 0xFFFFFFFFull)
      return status(c, 2, "subscribe: each subscription needs an unsigned 32-bit 'id' and a 'channelId'");
    const auto id = s["id"].get<std::uint32_t>();
    const std::uint64_t channel = s["channelId"].get<std::uint64_t>();
    if (channel < 1 || channel > channels_.size())
      status(c, 2, "subscribe: no channel " + std::to_string(channel));
    else if (c.subscriptions.count(id))
      status(c, 2, "subscribe: subscription id " + std::to_string(id) + " is in use");
    else if (c.subscriptions.size() >= options_.max_subscriptions)
      status(c, 2, "subscribe: at most " + std::to_string(options_.max_subscriptions) + " subscriptions");
    else {
      c.subscriptions[id] = static_cast<std::uint32_t>(channel);
      ++subscribers_[channel - 1];
    }
  }
}

void LiveServer::status(Client& c, int level, const std::string& message) {
  if (c.out_bytes > options_.max_queued_bytes) return;  // a client that floods is not answered
  c.queue(frame(Opcode::kText, nlohmann::json{{"op", "status"}, {"level", level}, {"message", message}}.dump()));
}

void LiveServer::close_with(Client& c, std::uint16_t code, const std::string& why) {
  std::string payload;
  payload.push_back(static_cast<char>(code >> 8));
  payload.push_back(static_cast<char>(code & 0xFF));
  payload += why.substr(0, 120);
  c.queue(frame(Opcode::kClose, payload));
  c.closing = true;
  if (code != 1000) ++stats_.refused;
}

}  // namespace foxglove
