// An MCAP reader for untrusted files (a recording may come from anywhere): one linear pass
// over every record, each length checked against the file's end and a bound before anything
// is allocated, every chunk's CRC and size checked, every message's channel and every
// channel's schema defined before use. An error is one line: "<file>: offset N: what".
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
  std::uint64_t max_file_bytes = 8ull << 30;
  std::uint64_t max_record_bytes = 256u << 20;  // a chunk or a message: a VGA image is 0.9 MB
  std::uint32_t max_channels = 4096;
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
};

using MessageCallback = std::function<void(const Channel&, const MessageView&)>;

// Reads `bytes` (a whole file; `name` is what errors call it). Throws FormatError.
ReadSummary read_mcap(const std::string& bytes, const std::string& name, const MessageCallback& on_message,
                      const ReadLimits& limits = {});
// Reads a regular file (a FIFO or /proc file is refused, not waited on). Throws FormatError,
// or config::FileError when the file cannot be read.
ReadSummary read_mcap_file(const std::filesystem::path& file, const MessageCallback& on_message,
                           const ReadLimits& limits = {});

}  // namespace mcap
