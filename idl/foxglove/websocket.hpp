// The WebSocket protocol (RFC 6455) as a live view's server needs it: the opening handshake,
// the frames it sends (unmasked, whole) and a reader of the frames a client sends (masked,
// whole, small). Pure functions over bytes: the sockets are live_server's.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace foxglove {

// the subprotocol a Foxglove client asks for, and the only one served
inline constexpr const char* kSubprotocol = "foxglove.websocket.v1";
// a client's opening request may be this long (header lines included); longer is refused
inline constexpr std::size_t kMaxHandshakeBytes = 8192;

// Sec-WebSocket-Accept for a client's Sec-WebSocket-Key: base64(SHA-1(key + the RFC's GUID)).
std::string accept_key(const std::string& key);

// A client's opening request, read up to and including its blank line.
struct Handshake {
  std::string key;              // Sec-WebSocket-Key
  bool offers_subprotocol = false;  // Sec-WebSocket-Protocol lists kSubprotocol
  std::string error;            // why the request is refused; empty: accepted
};
Handshake parse_handshake(std::string_view request);
// the server's 101 answer, selecting kSubprotocol
std::string handshake_reply(const std::string& key);
// a 400 answer with the reason as its body
std::string refusal(const std::string& why);

enum class Opcode : std::uint8_t { kContinuation = 0, kText = 1, kBinary = 2, kClose = 8, kPing = 9, kPong = 10 };

// One whole frame as the server sends it (FIN set, no mask).
std::string frame(Opcode op, std::string_view payload);
// the frame header alone, for a payload the caller appends
std::string frame_header(Opcode op, std::uint64_t payload_bytes);

struct Frame {
  Opcode opcode = Opcode::kText;
  std::string payload;
};

// Reads a client's frames from its byte stream. A client must mask every frame (RFC 6455
// §5.1), send it whole (no fragments: a Foxglove client's messages are small JSON texts) and
// keep each payload within kMaxPayload; a control frame within 125 bytes. Anything else is a
// protocol error: feed() returns false and error() says which; the connection is to be closed.
class FrameReader {
 public:
  static constexpr std::size_t kMaxPayload = 64 * 1024;
  bool feed(const char* data, std::size_t n, std::vector<Frame>& out);
  const std::string& error() const { return error_; }

 private:
  bool next(std::vector<Frame>& out, bool& more);
  bool fail(const char* why) {
    error_ = why;
    return false;
  }
  std::string buffer_;
  std::string error_;
};

}  // namespace foxglove
