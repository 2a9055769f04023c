#include "mcap/mcap_writer.hpp"

#include <fcntl.h>
#include <stdio.h>  // renameat2
#include <unistd.h>
#include <zlib.h>

#include <cerrno>
#include <cstring>

#include <stdexcept>
#include <system_error>

namespace mcap {

void put_u16(std::string& out, std::uint16_t v) {
  for (int i = 0; i < 2; ++i) out += static_cast<char>((v >> (8 * i)) & 0xff);
}
void put_u32(std::string& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out += static_cast<char>((v >> (8 * i)) & 0xff);
}
void put_u64(std::string& out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) out += static_cast<char>((v >> (8 * i)) & 0xff);
}
void put_string(std::string& out, const std::string& s) {
  put_u32(out, static_cast<std::uint32_t>(s.size()));
  out += s;
}

std::string record(std::uint8_t opcode, const std::string& content) {
  std::string r;
  r.reserve(9 + content.size());
  r += static_cast<char>(opcode);
  put_u64(r, content.size());
  r += content;
  return r;
}

std::uint32_t crc32(const std::string& bytes, std::uint32_t crc) {
  // zlib's crc32 is the spec's (IEEE 802.3, reflected); fed in pieces below 4 GiB
  uLong c = crc;
  std::size_t at = 0;
  while (at < bytes.size()) {
    const std::size_t n = std::min<std::size_t>(bytes.size() - at, 1u << 30);
    c = ::crc32(c, reinterpret_cast<const Bytef*>(bytes.data() + at), static_cast<uInt>(n));
    at += n;
  }
  return static_cast<std::uint32_t>(c);
}

namespace {

std::string key_values(const KeyValues& kv) {
  std::string body;
  for (const auto& [k, v] : kv) {
    put_string(body, k);
    put_string(body, v);
  }
  std::string out;
  put_string(out, body);  // a map is a uint32 byte length and its entries
  return out;
}

}  // namespace

Writer::Writer(const std::filesystem::path& file, WriterOptions options) : file_(file), options_(std::move(options)) {
  if (file.empty()) throw std::runtime_error("the recording's file name is empty");
  std::error_code ec;
  if (std::filesystem::exists(std::filesystem::symlink_status(file, ec)))
    throw std::runtime_error(file.string() + ": exists; a recording never replaces a file (name another, or move it away)");
  const std::filesystem::path partial = partial_file();
  // O_EXCL: never a file that exists (another recorder's, a killed one's, a link planted there)
  fd_ = ::open(partial.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW | O_NOCTTY, 0644);
  if (fd_ < 0) {
    const int e = errno;
    if (e == EEXIST)
      throw std::runtime_error(partial.string() + ": exists: another recording is being written there, or a stopped "
                               "one left it (servo replay reads it; move it away to record here)");
    throw std::runtime_error(partial.string() + ": cannot create the recording: " + std::strerror(e));
  }
  try {
    std::string head(kMagic, sizeof kMagic);
    std::string header;
    put_string(header, options_.profile);
    put_string(header, options_.library);
    head += record(kHeader, header);
    put(head);
    commit();
  } catch (...) {
    abandon();
    throw;
  }
}

Writer::~Writer() {
  try {
    close();
  } catch (...) {
    // a destructor must not throw; close() reports what failed in its summary
  }
}

std::filesystem::path Writer::partial_file() const { return std::filesystem::path(file_.string() + ".partial"); }

void Writer::abandon() {
  if (closed_) return;
  closed_ = true;
  ::close(fd_);
  fd_ = -1;
  ::unlink(partial_file().c_str());  // ours: created above with O_EXCL
}

void Writer::fail(const std::string& what) const { throw std::runtime_error(file_.string() + ": " + what); }

void Writer::put(const std::string& bytes) { put(bytes.data(), bytes.size()); }

void Writer::put(const char* bytes, std::size_t n) {
  buffer_.append(bytes, n);
  offset_ += n;
  if (buffer_.size() >= (1u << 20)) flush_buffer();
}

void Writer::flush_buffer() {
  std::size_t done = 0;
  while (done < buffer_.size()) {
    const ssize_t w = ::write(fd_, buffer_.data() + done, buffer_.size() - done);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) write_failed(w < 0 ? errno : ENOSPC);
    done += static_cast<std::size_t>(w);
  }
  buffer_.clear();
}

void Writer::commit() {
  flush_buffer();
  committed_ = offset_;
  committed_stats_ = stats_;
  committed_start_ns_ = start_ns_;
  committed_end_ns_ = end_ns_;
}

void Writer::write_failed(int error) {
  if (failure_.empty())
    failure_ = file_.string() + ": write failed: " + std::strerror(error) + (error == ENOSPC ? " (the disk is full)" : "") +
               "; the recording keeps its first " + std::to_string(committed_ >> 20) + " MB";
  // back to the last complete record: the open chunk, and whatever of it reached the disk, go
  buffer_.clear();
  chunk_open_ = false;
  chunk_index_.clear();
  stats_ = committed_stats_;
  start_ns_ = committed_start_ns_;
  end_ns_ = committed_end_ns_;
  offset_ = committed_;
  if (::ftruncate(fd_, static_cast<off_t>(committed_)) != 0 || ::lseek(fd_, static_cast<off_t>(committed_), SEEK_SET) < 0) {
    // nothing more to do: the reader stops at the first record that runs past the end
  }
  throw std::runtime_error(failure_);
}

// The open chunk's records go straight to the file behind a header that flush_chunk()
// completes: an image is copied once (into the file), and read once (for the chunk's CRC).
// Until then the header claims a chunk that runs past any file's end: a reader of a file
// whose writer was killed stops there, a truncation, having read every complete chunk.
void Writer::chunk_put(const char* bytes, std::size_t n) {
  if (!chunk_open_) {
    chunk_open_ = true;
    chunk_at_ = offset_;
    chunk_size_ = 0;
    chunk_crc_ = 0;
    std::string placeholder(kChunkHeaderBytes, '\0');
    placeholder[0] = static_cast<char>(kChunk);
    for (int i = 1; i <= 8; ++i) placeholder[i] = '\xff';
    put(placeholder);
  }
  put(bytes, n);
  chunk_crc_ = static_cast<std::uint32_t>(::crc32(chunk_crc_, reinterpret_cast<const Bytef*>(bytes), static_cast<uInt>(n)));
  chunk_size_ += n;
}

std::uint16_t Writer::add_schema(const std::string& name, const std::string& encoding, const std::string& data) {
  if (schemas_.size() >= 0xfffe) fail("too many schemas");
  const auto id = static_cast<std::uint16_t>(schemas_.size() + 1);
  std::string c;
  put_u16(c, id);
  put_string(c, name);
  put_string(c, encoding);
  put_string(c, data);
  schemas_.push_back(record(kSchema, c));
  chunk_put(schemas_.back().data(), schemas_.back().size());  // before the first message that needs it
  return id;
}

std::uint16_t Writer::add_channel(std::uint16_t schema_id, const std::string& topic, const std::string& message_encoding,
                                  const KeyValues& metadata) {
  if (channels_.size() >= 0xfffe) fail("too many channels");
  if (schema_id > schemas_.size()) fail("channel " + topic + " names an unknown schema");
  const auto id = static_cast<std::uint16_t>(channels_.size() + 1);
  std::string c;
  put_u16(c, id);
  put_u16(c, schema_id);
  put_string(c, topic);
  put_string(c, message_encoding);
  c += key_values(metadata);
  channels_.push_back(record(kChannel, c));
  chunk_put(channels_.back().data(), channels_.back().size());
  channel_topics_[id] = topic;
  stats_.channel_messages[id] = 0;
  return id;
}

void Writer::write_message(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time_ns,
                           std::uint64_t publish_time_ns, const std::uint8_t* data, std::size_t size) {
  if (closed_) fail("message after close");
  if (!failure_.empty()) throw std::runtime_error(failure_);
  if (channel_id == 0 || channel_id > channels_.size()) fail("message on an unknown channel");
  if (size > 0xffffffffu) fail("a message of more than 4 GB");
  if (chunk_open_ && chunk_size_ > 0 && chunk_size_ + size > options_.chunk_bytes) flush_chunk();
  const bool first_in_chunk = chunk_index_.empty();
  chunk_index_[channel_id].emplace_back(log_time_ns, chunk_open_ ? chunk_size_ : 0);
  std::string c;
  c.reserve(31);
  c += static_cast<char>(kMessage);
  put_u64(c, 22 + size);
  put_u16(c, channel_id);
  put_u32(c, sequence);
  put_u64(c, log_time_ns);
  put_u64(c, publish_time_ns);
  chunk_put(c.data(), c.size());
  chunk_put(reinterpret_cast<const char*>(data), size);
  if (first_in_chunk || log_time_ns < chunk_start_ns_) chunk_start_ns_ = log_time_ns;
  if (first_in_chunk || log_time_ns > chunk_end_ns_) chunk_end_ns_ = log_time_ns;
  if (stats_.messages == 0 || log_time_ns < start_ns_) start_ns_ = log_time_ns;
  if (stats_.messages == 0 || log_time_ns > end_ns_) end_ns_ = log_time_ns;
  ++stats_.messages;
  ++stats_.channel_messages[channel_id];
}

void Writer::add_metadata(const std::string& name, const KeyValues& values) {
  if (closed_) fail("metadata after close");
  // (tried after a failed write too: the file was cut back to its last complete record, and
  // the record that says why the recording stopped is the one a reader needs most)
  flush_chunk();  // metadata records are not allowed inside a chunk
  std::string c;
  put_string(c, name);
  c += key_values(values);
  const std::string r = record(kMetadata, c);
  const std::uint64_t at = offset_;
  put(r);
  commit();
  metadata_index_.emplace_back(name, at);
  metadata_lengths_.push_back(r.size());
}

// Completes the open chunk's header, then writes its Message Index records (one per channel).
void Writer::flush_chunk() {
  if (!chunk_open_) return;
  chunk_open_ = false;
  ChunkIndex ix{};
  ix.start_ns = chunk_index_.empty() ? 0 : chunk_start_ns_;
  ix.end_ns = chunk_index_.empty() ? 0 : chunk_end_ns_;
  ix.offset = chunk_at_;
  ix.records_size = chunk_size_;
  std::string head;
  head += static_cast<char>(kChunk);
  put_u64(head, kChunkHeaderBytes - 9 + chunk_size_);
  put_u64(head, ix.start_ns);
  put_u64(head, ix.end_ns);
  put_u64(head, chunk_size_);
  put_u32(head, chunk_crc_);
  put_string(head, "");  // uncompressed: Debian has zstd and lz4, but a 2-core loop has no time to spare
  put_u64(head, chunk_size_);
  flush_buffer();  // the header's bytes are in the file before they are written over
  if (::pwrite(fd_, head.data(), head.size(), static_cast<off_t>(chunk_at_)) != static_cast<ssize_t>(head.size()))
    write_failed(errno != 0 ? errno : ENOSPC);
  ix.length = offset_ - ix.offset;
  const std::uint64_t index_start = offset_;
  for (const auto& [channel, entries] : chunk_index_) {
    std::string m;
    put_u16(m, channel);
    put_u32(m, static_cast<std::uint32_t>(entries.size() * 16));
    for (const auto& [t, off] : entries) {
      put_u64(m, t);
      put_u64(m, off);
    }
    ix.message_index_offsets[channel] = offset_;
    put(record(kMessageIndex, m));
  }
  ix.message_index_length = offset_ - index_start;
  chunk_index_.clear();
  flush_buffer();  // the chunk and its indexes whole in the file before they are indexed
  chunk_indexes_.push_back(std::move(ix));
  ++stats_.chunks;
  commit();
}

// The summary's records, grouped by opcode (each group's bytes and opcode returned for the
// summary offsets).
std::string Writer::summary_section(std::vector<std::string>& groups, std::vector<std::uint8_t>& opcodes) {
  auto group = [&](std::uint8_t op, std::string bytes) {
    if (bytes.empty()) return;
    groups.push_back(std::move(bytes));
    opcodes.push_back(op);
  };
  std::string s;
  for (const auto& r : schemas_) s += r;
  group(kSchema, s);
  s.clear();
  for (const auto& r : channels_) s += r;
  group(kChannel, s);
  s.clear();
  for (const auto& ix : chunk_indexes_) {
    std::string c;
    put_u64(c, ix.start_ns);
    put_u64(c, ix.end_ns);
    put_u64(c, ix.offset);
    put_u64(c, ix.length);
    std::string offsets;
    for (const auto& [ch, off] : ix.message_index_offsets) {
      put_u16(offsets, ch);
      put_u64(offsets, off);
    }
    put_string(c, offsets);
    put_u64(c, ix.message_index_length);
    put_string(c, "");
    put_u64(c, ix.records_size);
    put_u64(c, ix.records_size);
    s += record(kChunkIndex, c);
  }
  group(kChunkIndex, s);
  s.clear();
  for (std::size_t i = 0; i < metadata_index_.size(); ++i) {
    std::string c;
    put_u64(c, metadata_index_[i].second);
    put_u64(c, metadata_lengths_[i]);
    put_string(c, metadata_index_[i].first);
    s += record(kMetadataIndex, c);
  }
  group(kMetadataIndex, s);
  std::string st;
  put_u64(st, stats_.messages);
  put_u16(st, static_cast<std::uint16_t>(schemas_.size()));
  put_u32(st, static_cast<std::uint32_t>(channels_.size()));
  put_u32(st, 0);  // attachments
  put_u32(st, static_cast<std::uint32_t>(metadata_index_.size()));
  put_u32(st, stats_.chunks);
  put_u64(st, stats_.messages ? start_ns_ : 0);
  put_u64(st, stats_.messages ? end_ns_ : 0);
  std::string counts;
  for (const auto& [ch, n] : stats_.channel_messages) {
    put_u16(counts, ch);
    put_u64(counts, n);
  }
  put_string(st, counts);
  group(kStatistics, record(kStatistics, st));
  std::string all;
  for (const auto& g : groups) all += g;
  return all;
}

WriteSummary Writer::close() {
  if (closed_) return stats_;
  closed_ = true;
  try {
    flush_chunk();
  } catch (const std::exception&) {
    // failure_ says it; the open chunk is dropped, the summary is still tried
  }
  try {
    finish();
    stats_.complete = true;
  } catch (const std::exception&) {
    // failure_ says it; the file ends at its last complete record
  }
  ::close(fd_);
  fd_ = -1;
  stats_.bytes = offset_;
  stats_.problem = failure_;
  stats_.file = partial_file();
  // renameat2's RENAME_NOREPLACE: a file that appeared at the name meanwhile is not replaced
  if (::renameat2(AT_FDCWD, partial_file().c_str(), AT_FDCWD, file_.c_str(), RENAME_NOREPLACE) == 0) {
    stats_.file = file_;
  } else {
    const int e = errno;
    stats_.problem += (stats_.problem.empty() ? "" : "; ") + file_.string() +
                      (e == EEXIST ? ": appeared while recording, and is not replaced"
                                   : std::string(": cannot be named so: ") + std::strerror(e)) +
                      "; the recording is " + partial_file().string();
  }
  for (const auto& [ch, n] : stats_.channel_messages) stats_.topic_messages[channel_topics_[ch]] += n;
  return stats_;
}

void Writer::finish() {
  std::string end;
  // 0: "not available". Every chunk carries its CRC; a second pass over every byte would
  // cost the lockstep loop more than the recording is allowed to (docs/performance.md)
  put_u32(end, 0);
  put(record(kDataEnd, end));
  const std::uint64_t summary_start = offset_;
  std::vector<std::string> groups;
  std::vector<std::uint8_t> opcodes;
  std::string tail = summary_section(groups, opcodes);
  const std::uint64_t offsets_start = summary_start + tail.size();
  std::uint64_t at = summary_start;
  for (std::size_t i = 0; i < groups.size(); ++i) {
    std::string c;
    c += static_cast<char>(opcodes[i]);
    put_u64(c, at);
    put_u64(c, groups[i].size());
    tail += record(kSummaryOffset, c);
    at += groups[i].size();
  }
  std::string footer;
  footer += static_cast<char>(kFooter);
  put_u64(footer, 20);
  put_u64(footer, summary_start);
  put_u64(footer, offsets_start);
  // the summary's CRC runs from its start through the footer's two offsets
  const std::uint32_t summary_crc = crc32(footer, crc32(tail));
  put_u32(footer, summary_crc);
  tail += footer;
  tail.append(kMagic, sizeof kMagic);
  put(tail);
  flush_buffer();
}

}  // namespace mcap
