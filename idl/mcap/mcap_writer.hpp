// An MCAP writer (https://mcap.dev/spec, major version 0), written from the specification:
// no Debian package carries an MCAP library. It writes what rosbag2's MCAP storage and
// Foxglove read and seek in: the header and its profile, schemas and channels, messages in
// uncompressed chunks with their message indexes and CRCs, the data end, and a summary
// (schemas, channels, chunk indexes, metadata indexes, statistics) with its summary offsets
// and CRC. Plain C++ and zlib's crc32: no DDS here.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace mcap {

using KeyValues = std::map<std::string, std::string>;

struct WriterOptions {
  std::string profile = "ros2";
  std::string library = "cellsim";
  // a chunk is written when it holds this much; a larger message gets a chunk of its own
  std::size_t chunk_bytes = 4u << 20;
};

// What was written, as the summary's statistics record says it.
struct WriteSummary {
  std::filesystem::path file;  // where the recording is (its own name, or NAME.partial: `problem`)
  bool complete = false;       // summary and footer written; false: truncated, its complete chunks readable
  std::string problem;         // why the recording is short, truncated or left as .partial (empty: none)
  std::uint64_t messages = 0;
  std::uint32_t chunks = 0;
  std::uint64_t bytes = 0;  // the file's size
  std::map<std::uint16_t, std::uint64_t> channel_messages;  // by channel id
  std::map<std::string, std::uint64_t> topic_messages;      // the same by topic
};

// A recording never replaces a file (issue 40, item 1): `file` must not exist; the bytes go to
// `file.partial`, created here and never if it exists (another recorder is writing it, or a
// killed one left it), and it becomes `file` when closed, by a rename that does not replace
// a `file` that appeared meanwhile. A killed recorder leaves `file.partial`, whose complete
// chunks a reader reads (ReadLimits::allow_truncated): an open chunk's header says it runs
// to the end of the file until it is complete.
//
// A failed write (a full disk) drops the open chunk, cuts the file back to the last complete
// record and refuses every later message; close() then writes the summary and footer if the
// disk has room again, and leaves the file cut at a record's end if not: readable either way.
class Writer {
 public:
  // Throws std::runtime_error naming the file when it exists, when `file.partial` exists or
  // cannot be created, or when the name is empty.
  Writer(const std::filesystem::path& file, WriterOptions options = {});
  ~Writer();  // closes (summary and footer) if neither close() nor abandon() was called; never throws
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  // ids from 1, in order of addition
  std::uint16_t add_schema(const std::string& name, const std::string& encoding, const std::string& data);
  std::uint16_t add_channel(std::uint16_t schema_id, const std::string& topic, const std::string& message_encoding,
                            const KeyValues& metadata);
  // Appends one message to the current chunk. Throws std::runtime_error naming the file on an
  // unknown channel or a failed write.
  void write_message(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time_ns,
                     std::uint64_t publish_time_ns, const std::uint8_t* data, std::size_t size);
  // A metadata record (written between chunks, indexed in the summary). Also after a write
  // failed (the messages are no longer taken): it may fail again, and then throws.
  void add_metadata(const std::string& name, const KeyValues& values);

  // Writes the last chunk, the data end, the summary and the footer, and renames the file to
  // its name. Idempotent; never throws for a write or a rename that fails: the summary's
  // `problem` says what happened and `file` where the bytes are.
  WriteSummary close();
  // Start-up failed: the partial file this writer created is removed (nothing else is).
  void abandon();
  const std::filesystem::path& file() const { return file_; }
  std::filesystem::path partial_file() const;
  std::uint64_t bytes_written() const { return offset_; }
  // why writing stopped (the disk is full), in one line; empty while it has not
  const std::string& failure() const { return failure_; }

 private:
  struct ChunkIndex {
    std::uint64_t start_ns, end_ns, offset, length, message_index_length, records_size;
    std::map<std::uint16_t, std::uint64_t> message_index_offsets;
  };
  void put(const std::string& bytes);  // to the end of the file (buffered)
  void put(const char* bytes, std::size_t n);
  void flush_buffer();                 // the buffer to the file
  void commit();                       // flushes: what is written so far is whole records
  [[noreturn]] void write_failed(int error);  // cuts back to the last commit, refuses what follows
  void finish();                       // data end, summary, footer (close's part that can fail)
  void chunk_put(const char* bytes, std::size_t n);  // into the open chunk (opened if need be)
  void flush_chunk();
  // opcode, length, start, end, uncompressed size, CRC, compression "", records length
  static constexpr std::size_t kChunkHeaderBytes = 1 + 8 + 8 + 8 + 8 + 4 + 4 + 8;
  std::string summary_section(std::vector<std::string>& groups, std::vector<std::uint8_t>& opcodes);
  void fail(const std::string& what) const;

  std::filesystem::path file_;
  WriterOptions options_;
  int fd_ = -1;
  std::string buffer_;  // bytes not yet in the file (flushed at 1 MB and at every commit)
  std::uint64_t offset_ = 0;     // the file's size once the buffer is flushed
  std::uint64_t committed_ = 0;  // the end of the last complete record in the file
  std::string failure_;
  bool closed_ = false;
  std::vector<std::string> schemas_, channels_;  // their records, for the summary
  std::map<std::uint16_t, std::string> channel_topics_;
  std::vector<std::pair<std::string, std::uint64_t>> metadata_index_;  // name, offset (and length below)
  std::vector<std::uint64_t> metadata_lengths_;
  // the open chunk: its header's place in the file, its records' size and CRC so far
  bool chunk_open_ = false;
  std::uint64_t chunk_at_ = 0, chunk_size_ = 0;
  std::uint32_t chunk_crc_ = 0;
  std::uint64_t chunk_start_ns_ = 0, chunk_end_ns_ = 0;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> chunk_index_;  // log time, offset
  std::vector<ChunkIndex> chunk_indexes_;
  WriteSummary stats_;
  std::uint64_t start_ns_ = 0, end_ns_ = 0;
  // the statistics at the last commit: a dropped chunk's messages are not counted
  WriteSummary committed_stats_;
  std::uint64_t committed_start_ns_ = 0, committed_end_ns_ = 0;
};

// Serialisation of the spec's primitive types, little-endian (shared with the reader's tests).
void put_u16(std::string& out, std::uint16_t v);
void put_u32(std::string& out, std::uint32_t v);
void put_u64(std::string& out, std::uint64_t v);
void put_string(std::string& out, const std::string& s);
// <opcode><uint64 length><content>
std::string record(std::uint8_t opcode, const std::string& content);
std::uint32_t crc32(const std::string& bytes, std::uint32_t crc = 0);

inline constexpr char kMagic[8] = {'\x89', 'M', 'C', 'A', 'P', '0', '\r', '\n'};
enum Opcode : std::uint8_t {
  kHeader = 0x01, kFooter = 0x02, kSchema = 0x03, kChannel = 0x04, kMessage = 0x05, kChunk = 0x06,
  kMessageIndex = 0x07, kChunkIndex = 0x08, kAttachment = 0x09, kAttachmentIndex = 0x0A, kStatistics = 0x0B,
  kMetadata = 0x0C, kMetadataIndex = 0x0D, kSummaryOffset = 0x0E, kDataEnd = 0x0F
};

}  // namespace mcap
