// The live view's WebSocket layer on bytes alone: the handshake, the frames it sends, and the
// client frames it refuses (foxglove/websocket.hpp).
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <string>
#include <vector>

#include "foxglove/live_server.hpp"
#include "foxglove/websocket.hpp"

namespace foxglove {
namespace {

std::string request(const std::string& extra = "Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n",
                    const std::string& key = "dGhlIHNhbXBsZSBub25jZQ==") {
  return "GET / HTTP/1.1\r\nHost: localhost\r\nUpgrade: websocket\r\nConnection: keep-alive, Upgrade\r\n"
         "Sec-WebSocket-Key: " + key + "\r\nSec-WebSocket-Version: 13\r\n" + extra + "\r\n";
}

// a client frame: masked with `mask`, FIN set unless `fin` is false
std::string client_frame(std::uint8_t opcode, const std::string& payload, bool masked = true, bool fin = true) {
  std::string f(1, static_cast<char>((fin ? 0x80 : 0) | opcode));
  const std::uint8_t bit = masked ? 0x80 : 0;
  if (payload.size() < 126) {
    f.push_back(static_cast<char>(bit | payload.size()));
  } else if (payload.size() < 65536) {
    f.push_back(static_cast<char>(bit | 126));
    f.push_back(static_cast<char>(payload.size() >> 8));
    f.push_back(static_cast<char>(payload.size() & 0xFF));
  } else {
    f.push_back(static_cast<char>(bit | 127));
    for (int i = 7; i >= 0; --i) f.push_back(static_cast<char>((static_cast<std::uint64_t>(payload.size()) >> (8 * i)) & 0xFF));
  }
  const char mask[4] = {0x12, 0x34, 0x56, 0x78};
  if (masked) f.append(mask, 4);
  for (std::size_t i = 0; i < payload.size(); ++i) f.push_back(masked ? static_cast<char>(payload[i] ^ mask[i % 4]) : payload[i]);
  return f;
}

TEST(WebSocket, TheAcceptKeyIsTheRfcsExample) {
  // RFC 6455, section 1.3
  EXPECT_EQ(accept_key("dGhlIHNhbXBsZSBub25jZQ=="), "s3pPLMBiTxaQ9kYGzzhZRbK+xOo=");
}

TEST(WebSocket, AFoxgloveHandshakeIsAcceptedAndAnsweredWithItsSubprotocol) {
  const Handshake h = parse_handshake(request());
  EXPECT_EQ(h.error, "");
  const std::string reply = handshake_reply(h.key);
  EXPECT_EQ(reply.rfind("HTTP/1.1 101", 0), 0u);
  EXPECT_NE(reply.find("Sec-WebSocket-Accept: s3pPLMBiTxaQ9kYGzzhZRbK+xOo=\r\n"), std::string::npos);
  EXPECT_NE(reply.find("Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n"), std::string::npos);
}

TEST(WebSocket, EveryBadHandshakeIsRefusedWithItsReason) {
  EXPECT_NE(parse_handshake(request("")).error.find("foxglove.websocket.v1"), std::string::npos);
  EXPECT_NE(parse_handshake(request("Sec-WebSocket-Protocol: x\r\n", "short")).error.find("24 base64"), std::string::npos);
  EXPECT_NE(parse_handshake("POST / HTTP/1.1\r\n\r\n").error.find("GET"), std::string::npos);
  EXPECT_NE(parse_handshake("GET / HTTP/1.1\r\nno colon here\r\n\r\n").error.find("':'"), std::string::npos);
  EXPECT_NE(parse_handshake("GET / HTTP/1.1\r\nHost: x\r\n\r\n").error.find("upgrade"), std::string::npos);
  EXPECT_NE(parse_handshake(std::string(9000, 'a')).error.find("8192"), std::string::npos);
  std::string v12 = request();
  v12.replace(v12.find("Version: 13"), 11, "Version: 12");
  EXPECT_NE(parse_handshake(v12).error.find("13"), std::string::npos);
  EXPECT_EQ(refusal("why").rfind("HTTP/1.1 400", 0), 0u);
}

TEST(WebSocket, ServerFramesCarryTheirLengthInTheShortestForm) {
  EXPECT_EQ(frame(Opcode::kText, std::string(125, 'x')).size(), 2u + 125);
  EXPECT_EQ(frame(Opcode::kText, std::string(126, 'x')).size(), 4u + 126);
  EXPECT_EQ(frame(Opcode::kBinary, std::string(65536, 'x')).size(), 10u + 65536);
  const std::string f = frame(Opcode::kBinary, "ab");
  EXPECT_EQ(static_cast<unsigned char>(f[0]), 0x82);  // FIN, binary
  EXPECT_EQ(static_cast<unsigned char>(f[1]), 2);     // no mask: a server never masks
}

TEST(WebSocket, ClientFramesAreReadWholeHoweverTheBytesArrive) {
  const std::string stream = client_frame(1, "{\"op\":\"subscribe\"}") + client_frame(9, "ping") +
                             client_frame(2, std::string(300, 'z'));
  FrameReader reader;
  std::vector<Frame> frames;
  for (char c : stream) ASSERT_TRUE(reader.feed(&c, 1, frames)) << reader.error();
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].opcode, Opcode::kText);
  EXPECT_EQ(frames[0].payload, "{\"op\":\"subscribe\"}");
  EXPECT_EQ(frames[1].opcode, Opcode::kPing);
  EXPECT_EQ(frames[2].payload, std::string(300, 'z'));
}

TEST(WebSocket, AFrameThatBreaksTheRulesIsAnErrorNamingIt) {
  const auto error_of = [](const std::string& bytes) {
    FrameReader reader;
    std::vector<Frame> frames;
    EXPECT_FALSE(reader.feed(bytes.data(), bytes.size(), frames));
    EXPECT_TRUE(frames.empty());
    return reader.error();
  };
  EXPECT_NE(error_of(client_frame(1, "x", false)).find("unmasked"), std::string::npos);
  EXPECT_NE(error_of(client_frame(1, "x", true, false)).find("fragmented"), std::string::npos);
  EXPECT_NE(error_of(client_frame(0, "x")).find("fragmented"), std::string::npos);
  EXPECT_NE(error_of(client_frame(3, "x")).find("unknown opcode"), std::string::npos);
  EXPECT_NE(error_of(client_frame(9, std::string(126, 'p'))).find("125"), std::string::npos);
  EXPECT_NE(error_of(client_frame(1, std::string(70000, 'x'))).find("65536"), std::string::npos);
  std::string reserved = client_frame(1, "x");
  reserved[0] = static_cast<char>(reserved[0] | 0x40);
  EXPECT_NE(error_of(reserved).find("reserved"), std::string::npos);
  // a header that claims 2^63 bytes: refused from its header, before any is buffered
  std::string huge = client_frame(2, std::string(70000, 'x')).substr(0, 10);
  huge[2] = static_cast<char>(0x7F);
  EXPECT_NE(error_of(huge).find("65536"), std::string::npos);
}

// The listening address: digits only, never a name looked up; loopback by default, another of
// this machine's addresses when asked (127.0.0.2 is loopback too: the test stays on the machine).
TEST(LiveServer, ListensWhereAskedAndRefusesANameInOneLine) {
  ServerOptions o;
  o.port = 0;
  {
    LiveServer server(o, "test", {});
    EXPECT_EQ(server.url(), "ws://127.0.0.1:" + std::to_string(server.port()));
  }
  o.address = "127.0.0.2";
  LiveServer other(o, "test", {});
  EXPECT_EQ(other.url().rfind("ws://127.0.0.2:", 0), 0U) << other.url();
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(other.port()));
  ::inet_pton(AF_INET, "127.0.0.2", &a.sin_addr);
  EXPECT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0) << "nothing listens on 127.0.0.2";
  ::close(fd);
  for (const std::string bad : {"localhost", "example.com", "::1", "127.0.0.256", "", "127.0.0.1 "}) {
    o.address = bad;
    try {
      LiveServer s(o, "test", {});
      ADD_FAILURE() << "'" << bad << "' was accepted";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("not an IPv4 address written in digits"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace foxglove
