#include "mcap/mcap_reader.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string_view>

#include "common/regular_file.hpp"

namespace mcap {
namespace {

// Where the bytes come from: a file read in order (never whole), or bytes in memory.
class Source {
 public:
  virtual ~Source() = default;
  virtual std::uint64_t size() const = 0;
  // the next n bytes into `out` (n is at most what is left: the caller checked)
  virtual void read(std::string& out, std::uint64_t n) = 0;
  virtual void skip(std::uint64_t n) = 0;
};

class MemorySource : public Source {
 public:
  explicit MemorySource(const std::string& b) : b_(b) {}
  std::uint64_t size() const override { return b_.size(); }
  void read(std::string& out, std::uint64_t n) override {
    out.assign(b_, static_cast<std::size_t>(at_), static_cast<std::size_t>(n));
    at_ += n;
  }
  void skip(std::uint64_t n) override { at_ += n; }

 private:
  const std::string& b_;
  std::uint64_t at_ = 0;
};

class FileSource : public Source {
 public:
  FileSource(const std::filesystem::path& file) : name_(file.string()) {
    std::uintmax_t size = 0;
    fd_ = common::open_regular_file(file, ~std::uintmax_t{0}, "recording", size);
    size_ = size;
  }
  ~FileSource() override { ::close(fd_); }
  FileSource(const FileSource&) = delete;
  FileSource& operator=(const FileSource&) = delete;
  std::uint64_t size() const override { return size_; }
  void read(std::string& out, std::uint64_t n) override {
    out.resize(static_cast<std::size_t>(n));
    std::size_t got = 0;
    while (got < out.size()) {
      const ssize_t r = ::read(fd_, out.data() + got, out.size() - got);
      if (r < 0 && errno == EINTR) continue;
      if (r < 0) throw common::FileError(name_ + ": cannot read the recording: " + std::strerror(errno));
      // the file shrank while it was read: what is missing reads as a truncation would
      if (r == 0) throw FormatError(name_ + ": the file shrank while it was read");
      got += static_cast<std::size_t>(r);
    }
  }
  void skip(std::uint64_t n) override {
    if (::lseek(fd_, static_cast<off_t>(n), SEEK_CUR) < 0)
      throw common::FileError(name_ + ": cannot read the recording: " + std::strerror(errno));
  }

 private:
  std::string name_;
  int fd_ = -1;
  std::uint64_t size_ = 0;
};

// A cursor over one record's content: every read checks what is left.
class Cursor {
 public:
  Cursor(std::string_view bytes, std::uint64_t file_offset, const std::string& file)
      : b_(bytes), base_(file_offset), file_(file) {}

  [[noreturn]] void fail(const std::string& what) const { fail_at(base_ + at_, what); }
  [[noreturn]] void fail_at(std::uint64_t offset, const std::string& what) const {
    throw FormatError(file_ + ": offset " + std::to_string(offset) + ": " + what);
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
    const std::uint64_t n = uint(4, field);
    const std::uint64_t at = offset();  // before bytes() moves past them
    Cursor m(bytes(n, field), at, file_);
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
      fail(std::string(field) + " claims " + std::to_string(n) + " bytes, past the record's end (" +
           std::to_string(b_.size() - at_) + " left)");
  }
  std::string_view b_;
  std::size_t at_ = 0;
  std::uint64_t base_;
  const std::string& file_;
};

// The end of a truncated file: thrown inside the reader, turned into ReadSummary::truncated
// or a FormatError by read().
struct Truncated {
  std::uint64_t offset;
  std::string what;
};

class LinearReader {
 public:
  LinearReader(Source& src, const std::string& name, const MessageCallback& cb, const ReadLimits& l)
      : src_(src), name_(name), cb_(cb), limits_(l), top_({}, 0, name) {}

  ReadSummary read() {
    std::string magic;
    if (src_.size() < sizeof kMagic) top_.fail_at(0, "wrong magic (not an MCAP file of major version 0)");
    src_.read(magic, sizeof kMagic);
    if (std::memcmp(magic.data(), kMagic, sizeof kMagic) != 0)
      top_.fail_at(0, "wrong magic (not an MCAP file of major version 0)");
    pos_ = sizeof kMagic;
    try {
      records();
    } catch (const Truncated& t) {
      const std::string what = "truncated: " + t.what + "; " + std::to_string(out_.chunks) + " complete chunks (" +
                               std::to_string(out_.messages) + " messages) before it";
      if (!limits_.allow_truncated) top_.fail_at(t.offset, what);
      out_.truncated = name_ + ": offset " + std::to_string(t.offset) + ": " + what;
    }
    return std::move(out_);
  }

 private:
  void records() {
    bool first = true, data_end = false;
    while (true) {
      const std::uint64_t at = pos_;
      const std::uint64_t left = src_.size() - pos_;
      if (left == 0) throw Truncated{at, "the file ends before its footer"};
      if (left < 9) throw Truncated{at, "the file ends inside a record's opcode and length"};
      std::string head;
      src_.read(head, 9);
      pos_ += 9;
      Cursor h(head, at, name_);
      const auto op = static_cast<std::uint8_t>(h.uint(1, "opcode"));
      const std::uint64_t len = h.uint(8, "record length");
      // opcode 0 is no record: 9 zero bytes would otherwise be read as an empty one, and a
      // file of zeros would take as long to refuse as it is large
      if (op == 0) h.fail_at(at, "opcode 0 is not a record");
      if (op != kChunk && len > limits_.max_record_bytes)
        h.fail_at(at, "a record of " + std::to_string(len) + " bytes, more than the limit of " +
                          std::to_string(limits_.max_record_bytes));
      if (len > src_.size() - pos_)
        throw Truncated{at, "a record of " + std::to_string(len) + " bytes runs past the file's end (" +
                                std::to_string(src_.size() - pos_) + " bytes left)"};
      if (first && op != kHeader) h.fail_at(at, "the first record is not a header");
      if (!first && op == kHeader) h.fail_at(at, "a second header");
      first = false;
      if (op == kDataEnd) data_end = true;
      if (data_end && (op == kMessage || op == kChunk)) h.fail_at(at, "a message after the data end");
      if (op == kChunk && len > limits_.max_record_bytes)
        h.fail_at(at, "a chunk of " + std::to_string(len) + " bytes, more than the limit of " +
                          std::to_string(limits_.max_record_bytes));
      if (!needed(op)) {
        src_.skip(len);  // indexes, attachments, offsets: framing checked, content not needed
        pos_ += len;
        if (data_end) out_.has_summary = out_.has_summary || op != kDataEnd;
        continue;
      }
      src_.read(content_, len);
      pos_ += len;
      Cursor c(content_, at + 9, name_);
      if (op == kFooter) {
        footer(c);
        return;
      }
      dispatch(op, c, at);
      if (data_end) out_.has_summary = true;
    }
  }

  static bool needed(std::uint8_t op) {
    return op == kHeader || op == kFooter || op == kSchema || op == kChannel || op == kMessage || op == kChunk ||
           op == kStatistics || op == kMetadata;
  }

  void footer(Cursor& c) {
    c.uint(8, "summary_start");
    c.uint(8, "summary_offset_start");
    c.uint(4, "summary_crc");
    const std::uint64_t left = src_.size() - pos_;
    if (left < sizeof kMagic) throw Truncated{pos_, "the file ends inside its trailing magic"};
    std::string magic;
    src_.read(magic, sizeof kMagic);
    if (std::memcmp(magic.data(), kMagic, sizeof kMagic) != 0) top_.fail_at(pos_, "wrong trailing magic");
    if (left != sizeof kMagic) top_.fail_at(pos_ + sizeof kMagic, "bytes after the trailing magic");
  }

  void dispatch(std::uint8_t op, Cursor& c, std::uint64_t at) {
    switch (op) {
      case kHeader:
        out_.profile = c.string("profile");
        out_.library = c.string("library");
        break;
      case kSchema: schema(c); break;
      case kChannel: channel(c); break;
      case kMessage: message(c); break;
      case kChunk: chunk(c, at); break;
      case kStatistics:
        out_.stated_messages = c.uint(8, "message_count");
        break;
      case kMetadata: {
        std::string name = c.string("name");
        out_.metadata[name] = c.key_values("metadata");
        break;
      }
      default:
        break;
    }
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

  void chunk(Cursor& c, std::uint64_t at) {
    c.uint(8, "message start time");
    c.uint(8, "message end time");
    const std::uint64_t size = c.uint(8, "uncompressed size");
    const auto crc = static_cast<std::uint32_t>(c.uint(4, "uncompressed crc"));
    const std::string compression = c.string("compression");
    const std::uint64_t n = c.uint(8, "records length");
    if (!compression.empty()) c.fail("chunk compression '" + compression.substr(0, 16) + "' is not supported (only none)");
    if (n != size) c.fail("chunk records length " + std::to_string(n) + " differs from its uncompressed size " + std::to_string(size));
    const std::uint64_t start = c.offset();
    const std::string_view records = c.bytes(n, "chunk records");
    if (crc != 0 && crc32(std::string(records)) != crc) c.fail_at(at, "chunk CRC mismatch");
    Cursor in(records, start, name_);
    while (!in.done()) {
      const std::uint64_t record_at = in.offset();
      const auto op = static_cast<std::uint8_t>(in.uint(1, "opcode"));
      const std::uint64_t len = in.uint(8, "record length");
      const std::uint64_t content_at = in.offset();  // before bytes() moves past the content
      Cursor r(in.bytes(len, "record"), content_at, name_);
      if (op == kSchema) schema(r);
      else if (op == kChannel) channel(r);
      else if (op == kMessage) message(r);
      else r.fail_at(record_at, "record of opcode " + std::to_string(op) +
                                    " inside a chunk (only schemas, channels and messages belong there)");
    }
    ++out_.chunks;
  }

  Source& src_;
  const std::string& name_;
  const MessageCallback& cb_;
  ReadLimits limits_;
  Cursor top_;              // for errors at file offsets outside a record
  std::uint64_t pos_ = 0;   // the source's offset
  std::string content_;     // the record being read (its buffer reused)
  ReadSummary out_;
};

}  // namespace

ReadSummary read_mcap(const std::string& bytes, const std::string& name, const MessageCallback& on_message,
                      const ReadLimits& limits) {
  MemorySource src(bytes);
  return LinearReader(src, name, on_message, limits).read();
}

ReadSummary read_mcap_file(const std::filesystem::path& file, const MessageCallback& on_message,
                           const ReadLimits& limits) {
  FileSource src(file);
  return LinearReader(src, file.string(), on_message, limits).read();
}

}  // namespace mcap
