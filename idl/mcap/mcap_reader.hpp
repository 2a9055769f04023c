// An MCAP reader for untrusted files (a recording may come from anywhere): one linear pass
// over every record, streamed (one record in memory at a time, so a file of any size reads
// in the memory of its largest chunk), each length checked against the file's end and a
// bound before anything is allocated, every chunk's CRC and size checked, every message's
// channel and every channel's schema defined before use. An error is one line:
// "<file>: offset N: what", N the offset of the record (or field) at fault.
//
// A file that ends before its footer (a recorder killed mid-run) is truncated, not malformed:
// with ReadLimits::allow_truncated its complete chunks are read and ReadSummary::truncated says
// where it ends, as rosbag2's and the MCAP tools' readers do; without, it is a FormatError.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "mcap/mcap_writer.hpp"

namespace mcap {

class FormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Schema {
  std::uint16_t id = 0;
  std::string name, encoding, data;
  bool operator==(const Schema&) const = default;
};

struct Channel {
  std::uint16_t id = 0, schema_id = 0;
  std::string topic, message_encoding;
  KeyValues metadata;
  bool operator==(const Channel&) const = default;
};

struct MessageView {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time_ns = 0, publish_time_ns = 0;
  const std::uint8_t* data = nullptr;  // valid during the callback only
  std::size_t size = 0;
};

struct ReadLimits {
  // no bound on the file: it is streamed. A chunk or a message: a VGA image is 0.9 MB, the
  // recorder's chunks 4 MB (a larger message gets a chunk of its own)
  std::uint64_t max_record_bytes = 256u << 20;
  std::uint32_t max_channels = 4096;
  bool allow_truncated = false;  // read a truncated file's complete records (see above)
};

struct ReadSummary {
  std::string profile, library;
  std::map<std::uint16_t, Schema> schemas;
  std::map<std::uint16_t, Channel> channels;
  std::uint64_t messages = 0;
  std::map<std::uint16_t, std::uint64_t> channel_messages;
  std::uint32_t chunks = 0;
  bool has_summary = false;             // a summary section was read
  std::optional<std::uint64_t> stated_messages;  // what its statistics record says
  std::map<std::string, KeyValues> metadata;  // by name
  // set when the file ends before its footer (allow_truncated): where and how, in one line
  std::optional<std::string> truncated;
};

using MessageCallback = std::function<void(const Channel&, const MessageView&)>;

// Reads `bytes` (a whole file; `name` is what errors call it). Throws FormatError. Messages
// reach `on_message` as they are read: a file found malformed later has already delivered
// the messages before the fault.
ReadSummary read_mcap(const std::string& bytes, const std::string& name, const MessageCallback& on_message,
                      const ReadLimits& limits = {});
// Reads a regular file (a FIFO or /proc file is refused, not waited on). Throws FormatError,
// or common::FileError when the file cannot be read.
ReadSummary read_mcap_file(const std::filesystem::path& file, const MessageCallback& on_message,
                           const ReadLimits& limits = {});

}  // namespace mcap
