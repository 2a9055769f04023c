#include "foxglove/websocket.hpp"

#include <openssl/evp.h>
#include <openssl/sha.h>

#include <algorithm>
#include <cctype>

namespace foxglove {

namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

// whether a comma-separated header value lists `token` (case-insensitive)
bool lists(std::string_view value, std::string_view token) {
  while (!value.empty()) {
    const std::size_t comma = value.find(',');
    if (lower(trim(value.substr(0, comma))) == lower(token)) return true;
    if (comma == std::string_view::npos) break;
    value.remove_prefix(comma + 1);
  }
  return false;
}

Handshake refused(Handshake h, const char* why) {
  h.error = why;
  return h;
}

}  // namespace

std::string accept_key(const std::string& key) {
  const std::string text = key + "258EAFA5-E914-47DA-95CA-C5AB0DC85B11";
  unsigned char digest[SHA_DIGEST_LENGTH];
  SHA1(reinterpret_cast<const unsigned char*>(text.data()), text.size(), digest);
  unsigned char out[4 * ((SHA_DIGEST_LENGTH + 2) / 3) + 1];
  const int n = EVP_EncodeBlock(out, digest, SHA_DIGEST_LENGTH);
  return std::string(reinterpret_cast<const char*>(out), static_cast<std::size_t>(n));
}

Handshake parse_handshake(std::string_view request) {
  Handshake h;
  if (request.size() > kMaxHandshakeBytes) return refused(h, "request longer than 8192 bytes");
  const std::size_t first_end = request.find("\r\n");
  const std::string_view first = request.substr(0, first_end);
  if (first.substr(0, 4) != "GET " || first.find(" HTTP/1.1") == std::string_view::npos)
    return refused(h, "not an HTTP/1.1 GET request");
  bool upgrade = false, connection = false, version = false;
  std::string_view rest = first_end == std::string_view::npos ? std::string_view() : request.substr(first_end + 2);
  while (!rest.empty()) {
    const std::size_t end = rest.find("\r\n");
    const std::string_view line = rest.substr(0, end);
    rest = end == std::string_view::npos ? std::string_view() : rest.substr(end + 2);
    if (line.empty()) break;
    const std::size_t colon = line.find(':');
    if (colon == std::string_view::npos) return refused(h, "a header line without ':'");
    const std::string name = lower(trim(line.substr(0, colon)));
    const std::string_view value = trim(line.substr(colon + 1));
    if (name == "upgrade") upgrade = lists(value, "websocket");
    else if (name == "connection") connection = lists(value, "upgrade");
    else if (name == "sec-websocket-version") version = value == "13";
    else if (name == "sec-websocket-key") h.key = std::string(value);
    else if (name == "sec-websocket-protocol") h.offers_subprotocol = h.offers_subprotocol || lists(value, kSubprotocol);
  }
  // the key is 16 random bytes in base64: 24 characters of the base64 alphabet
  const bool key_ok = h.key.size() == 24 && std::all_of(h.key.begin(), h.key.end(), [](char c) {
                        return std::isalnum(static_cast<unsigned char>(c)) || c == '+' || c == '/' || c == '=';
                      });
  if (!upgrade || !connection) h.error = "not a WebSocket upgrade (Upgrade: websocket, Connection: Upgrade)";
  else if (!version) h.error = "Sec-WebSocket-Version must be 13";
  else if (!key_ok) h.error = "Sec-WebSocket-Key must be 24 base64 characters";
  else if (!h.offers_subprotocol) h.error = std::string("Sec-WebSocket-Protocol must offer ") + kSubprotocol;
  return h;
}

std::string handshake_reply(const std::string& key) {
  return "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Accept: " +
         accept_key(key) + "\r\nSec-WebSocket-Protocol: " + kSubprotocol + "\r\n\r\n";
}

std::string refusal(const std::string& why) {
  const std::string body = why + "\n";
  return "HTTP/1.1 400 Bad Request\r\nContent-Type: text/plain\r\nConnection: close\r\nContent-Length: " +
         std::to_string(body.size()) + "\r\n\r\n" + body;
}

std::string frame_header(Opcode op, std::uint64_t n) {
  std::string h;
  h.push_back(static_cast<char>(0x80 | static_cast<std::uint8_t>(op)));
  if (n < 126) {
    h.push_back(static_cast<char>(n));
  } else if (n <= 0xFFFF) {
    h.push_back(static_cast<char>(126));
    for (int i = 1; i >= 0; --i) h.push_back(static_cast<char>((n >> (8 * i)) & 0xFF));
  } else {
    h.push_back(static_cast<char>(127));
    for (int i = 7; i >= 0; --i) h.push_back(static_cast<char>((n >> (8 * i)) & 0xFF));
  }
  return h;
}

std::string frame(Opcode op, std::string_view payload) {
  std::string f = frame_header(op, payload.size());
  f.append(payload);
  return f;
}

bool FrameReader::feed(const char* data, std::size_t n, std::vector<Frame>& out) {
  if (!error_.empty()) return false;
  buffer_.append(data, n);
  for (bool more = true; more;)
    if (!next(out, more)) return false;
  // what is left is one frame's beginning: a client cannot make the buffer grow past a frame
  if (buffer_.size() > kMaxPayload + 14) return fail("more unread bytes than one frame may have");
  return true;
}

// One frame off the buffer, if whole; `more` false when the buffer holds no whole frame.
bool FrameReader::next(std::vector<Frame>& out, bool& more) {
  more = false;
  const auto* b = reinterpret_cast<const unsigned char*>(buffer_.data());
  if (buffer_.size() < 2) return true;
  const bool fin = b[0] & 0x80, masked = b[1] & 0x80;
  const auto op = static_cast<Opcode>(b[0] & 0x0F);
  if (b[0] & 0x70) return fail("reserved bits set (no extension was agreed)");
  if (!masked) return fail("an unmasked frame from a client");
  if (!fin || op == Opcode::kContinuation) return fail("a fragmented message (not supported)");
  const bool control = op == Opcode::kClose || op == Opcode::kPing || op == Opcode::kPong;
  if (!control && op != Opcode::kText && op != Opcode::kBinary) return fail("an unknown opcode");
  std::uint64_t len = b[1] & 0x7F;
  std::size_t at = 2;
  if (len == 126 || len == 127) {
    const std::size_t bytes = len == 126 ? 2 : 8;
    if (buffer_.size() < at + bytes) return true;
    len = 0;
    for (std::size_t i = 0; i < bytes; ++i) len = (len << 8) | b[at + i];
    at += bytes;
  }
  if (control && len > 125) return fail("a control frame longer than 125 bytes");
  if (len > kMaxPayload) return fail("a frame longer than 65536 bytes");
  if (buffer_.size() < at + 4 + len) return true;
  const unsigned char* mask = b + at;
  at += 4;
  Frame f;
  f.opcode = op;
  f.payload.resize(static_cast<std::size_t>(len));
  for (std::size_t i = 0; i < len; ++i) f.payload[i] = static_cast<char>(b[at + i] ^ mask[i % 4]);
  buffer_.erase(0, at + static_cast<std::size_t>(len));
  out.push_back(std::move(f));
  more = true;
  return true;
}

}  // namespace foxglove
