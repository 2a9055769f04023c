#include "mcap/mcap_reader.hpp"

#include <cstring>
#include <string_view>

#include "servo/config/regular_file.hpp"

namespace mcap {
namespace {

// A cursor over one record's content: every read checks what is left.
class Cursor {
 public:
  Cursor(std::string_view bytes, std::uint64_t file_offset, const std::string& file, const char* whole = "the record")
      : b_(bytes), base_(file_offset), file_(file), whole_(whole) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw FormatError(file_ + ": offset " + std::to_string(base_ + at_) + ": " + what);
  }
  std::uint64_t uint(int bytes, const char* field) {
    need(static_cast<std::uint64_t>(bytes), field);
    std::uint64_t v = 0;
    for (int i = 0; i < bytes; ++i) v |= static_cast<std::uint64_t>(static_cast<unsigned char>(b_[at_ + i])) << (8 * i);
    at_ += static_cast<std::size_t>(bytes);
    return v;
  }
  std::string_view bytes(std::uint64_t n, const char* field) {
    need(n, field);
    const std::string_view v = b_.substr(at_, static_cast<std::size_t>(n));
    at_ += static_cast<std::size_t>(n);
    return v;
  }
  std::string string(const char* field) { return std::string(bytes(uint(4, field), field)); }
  KeyValues key_values(const char* field) {
    Cursor m(bytes(uint(4, field), field), base_ + at_, file_);
    KeyValues kv;
    while (!m.done()) {
      std::string k = m.string(field);
      kv[k] = m.string(field);
    }
    return kv;
  }
  std::string_view rest() { return bytes(b_.size() - at_, "data"); }
  bool done() const { return at_ == b_.size(); }
  std::uint64_t offset() const { return base_ + at_; }

 private:
  void need(std::uint64_t n, const char* field) const {
    if (n > b_.size() - at_)
      fail(std::string(field) + " claims " + std::to_string(n) + " bytes, past " + whole_ + "'s end (" +
           std::to_string(b_.size() - at_) + " left)");
  }
  std::string_view b_;
  std::size_t at_ = 0;
  std::uint64_t base_;
  const std::string& file_;
  const char* whole_;
};

class LinearReader {
 public:
  LinearReader(const std::string& bytes, const std::string& name, const MessageCallback& cb, const ReadLimits& l)
      : all_(bytes), name_(name), cb_(cb), limits_(l) {}

  ReadSummary read() {
    Cursor file(all_, 0, name_, "the file");
    if (all_.size() > limits_.max_file_bytes) file.fail("file larger than " + std::to_string(limits_.max_file_bytes) + " bytes");
    if (all_.size() < sizeof kMagic || std::memcmp(all_.data(), kMagic, sizeof kMagic) != 0)
      file.fail("wrong magic (not an MCAP file of major version 0)");
    file.bytes(sizeof kMagic, "magic");
    bool first = true, data_end = false;
    while (true) {
      if (file.done()) file.fail("truncated: the file ends before its footer");
      const std::uint64_t at = file.offset();
      const auto op = static_cast<std::uint8_t>(file.uint(1, "opcode"));
      const std::uint64_t len = file.uint(8, "record length");
      if (op != kChunk && len > limits_.max_record_bytes)
        Cursor(all_, at, name_).fail("a record of " + std::to_string(len) + " bytes, more than the limit of " +
                                     std::to_string(limits_.max_record_bytes));
      Cursor content(file.bytes(len, "record"), at + 9, name_);
      if (first && op != kHeader) content.fail("the first record is not a header");
      if (!first && op == kHeader) content.fail("a second header");
      first = false;
      if (op == kFooter) {
        footer(content, file);
        return std::move(out_);
      }
      if (op == kDataEnd) data_end = true;
      if (data_end && (op == kMessage || op == kChunk)) content.fail("a message after the data end");
      dispatch(op, content, data_end);
    }
  }

 private:
  void footer(Cursor& content, Cursor& file) {
    content.uint(8, "summary_start");
    content.uint(8, "summary_offset_start");
    content.uint(4, "summary_crc");
    const std::string_view magic = file.bytes(sizeof kMagic, "trailing magic");
    if (std::memcmp(magic.data(), kMagic, sizeof kMagic) != 0) file.fail("wrong trailing magic");
    if (!file.done()) file.fail("bytes after the trailing magic");
  }

  void dispatch(std::uint8_t op, Cursor& c, bool in_summary) {
    switch (op) {
      case kHeader:
        out_.profile = c.string("profile");
        out_.library = c.string("library");
        break;
      case kSchema: schema(c); break;
      case kChannel: channel(c); break;
      case kMessage: message(c); break;
      case kChunk: chunk(c); break;
      case kStatistics:
        out_.stated_messages = c.uint(8, "message_count");
        break;
      case kMetadata: {
        std::string name = c.string("name");
        out_.metadata[name] = c.key_values("metadata");
        break;
      }
      default:
        break;  // indexes, attachments, offsets, data end: framing checked above, content not needed
    }
    if (in_summary) out_.has_summary = true;
  }

  void schema(Cursor& c) {
    Schema s;
    s.id = static_cast<std::uint16_t>(c.uint(2, "schema id"));
    s.name = c.string("schema name");
    s.encoding = c.string("schema encoding");
    s.data = c.string("schema data");
    if (s.id == 0) return;  // the spec: ignored
    const auto [it, fresh] = out_.schemas.emplace(s.id, s);
    if (!fresh && !(it->second == s)) c.fail("schema " + std::to_string(s.id) + " defined twice, differently");
  }

  void channel(Cursor& c) {
    Channel ch;
    ch.id = static_cast<std::uint16_t>(c.uint(2, "channel id"));
    ch.schema_id = static_cast<std::uint16_t>(c.uint(2, "schema id"));
    ch.topic = c.string("topic");
    ch.message_encoding = c.string("message encoding");
    ch.metadata = c.key_values("channel metadata");
    if (ch.schema_id != 0 && !out_.schemas.count(ch.schema_id))
      c.fail("channel " + ch.topic + " names schema " + std::to_string(ch.schema_id) + ", which the file never defined");
    const auto [it, fresh] = out_.channels.emplace(ch.id, ch);
    if (!fresh && !(it->second == ch)) c.fail("channel " + std::to_string(ch.id) + " defined twice, differently");
    if (out_.channels.size() > limits_.max_channels) c.fail("more than " + std::to_string(limits_.max_channels) + " channels");
  }

  void message(Cursor& c) {
    MessageView m;
    m.channel_id = static_cast<std::uint16_t>(c.uint(2, "channel id"));
    m.sequence = static_cast<std::uint32_t>(c.uint(4, "sequence"));
    m.log_time_ns = c.uint(8, "log time");
    m.publish_time_ns = c.uint(8, "publish time");
    const std::string_view data = c.rest();
    m.data = reinterpret_cast<const std::uint8_t*>(data.data());
    m.size = data.size();
    const auto it = out_.channels.find(m.channel_id);
    if (it == out_.channels.end()) c.fail("a message on channel " + std::to_string(m.channel_id) + ", never defined");
    ++out_.messages;
    ++out_.channel_messages[m.channel_id];
    if (cb_) cb_(it->second, m);
  }

  void chunk(Cursor& c) {
    c.uint(8, "message start time");
    c.uint(8, "message end time");
    const std::uint64_t size = c.uint(8, "uncompressed size");
    const auto crc = static_cast<std::uint32_t>(c.uint(4, "uncompressed crc"));
    const std::string compression = c.string("compression");
    const std::uint64_t n = c.uint(8, "records length");
    if (!compression.empty()) c.fail("chunk compression '" + compression.substr(0, 16) + "' is not supported (only none)");
    if (n != size) c.fail("chunk records length " + std::to_string(n) + " differs from its uncompressed size " + std::to_string(size));
    if (n > limits_.max_record_bytes) c.fail("a chunk of " + std::to_string(n) + " bytes, more than the limit");
    const std::uint64_t start = c.offset();
    const std::string_view records = c.bytes(n, "chunk records");
    if (crc != 0 && crc32(std::string(records)) != crc) c.fail("chunk CRC mismatch");
    Cursor in(records, start, name_);
    while (!in.done()) {
      const auto op = static_cast<std::uint8_t>(in.uint(1, "opcode"));
      const std::uint64_t len = in.uint(8, "record length");
      Cursor r(in.bytes(len, "record"), in.offset() - len, name_);
      if (op == kSchema) schema(r);
      else if (op == kChannel) channel(r);
      else if (op == kMessage) message(r);
      else r.fail("record of opcode " + std::to_string(op) + " inside a chunk (only schemas, channels and messages belong there)");
    }
    ++out_.chunks;
  }

  const std::string& all_;
  const std::string& name_;
  const MessageCallback& cb_;
  ReadLimits limits_;
  ReadSummary out_;
};

}  // namespace

ReadSummary read_mcap(const std::string& bytes, const std::string& name, const MessageCallback& on_message,
                      const ReadLimits& limits) {
  return LinearReader(bytes, name, on_message, limits).read();
}

ReadSummary read_mcap_file(const std::filesystem::path& file, const MessageCallback& on_message,
                           const ReadLimits& limits) {
  const std::string bytes = config::read_regular_file(file, limits.max_file_bytes, "recording");
  return read_mcap(bytes, file.string(), on_message, limits);
}

}  // namespace mcap
