// The MCAP writer and reader (idl/mcap): what is written reads back record for record, and
// every malformed file the issue names (truncated, wrong magic, a length past the end, a
// 4 GB claimed length, an unknown schema or channel) is one error naming the file and offset.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "mcap/mcap_reader.hpp"
#include "mcap/mcap_writer.hpp"

namespace {

int last_child_code = 0;

std::filesystem::path temp_file(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("mcap_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir / name;
}

std::string slurp(const std::filesystem::path& f) {
  std::ifstream in(f, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// A file's first bytes: the magic and a header of profile "ros2", library "test".
std::string magic_and_header() {
  std::string file(mcap::kMagic, 8);
  std::string header;
  mcap::put_string(header, "ros2");
  mcap::put_string(header, "test");
  return file + mcap::record(mcap::kHeader, header);
}

// Two channels, `n` messages alternating between them, in chunks of `chunk_bytes`.
mcap::WriteSummary write_sample(const std::filesystem::path& f, int n, std::size_t chunk_bytes) {
  std::filesystem::remove(f);
  mcap::WriterOptions o;
  o.chunk_bytes = chunk_bytes;
  mcap::Writer w(f, o);
  const auto s = w.add_schema("std_msgs/msg/String", "ros2msg", "string data\n");
  const auto a = w.add_channel(s, "/a", "cdr", {{"offered_qos_profiles", "- history: keep_last"}});
  const auto b = w.add_channel(s, "/b", "cdr", {});
  w.add_metadata("cellsim", {{"scenario", "plane"}});
  for (int i = 0; i < n; ++i) {
    const std::string payload(static_cast<std::size_t>(10 + i), static_cast<char>('a' + i % 26));
    w.write_message(i % 2 ? b : a, static_cast<std::uint32_t>(i), 1000 + i, 900 + i,
                    reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size());
  }
  return w.close();
}

TEST(Mcap, WhatIsWrittenReadsBackMessageForMessage) {
  const auto f = temp_file("roundtrip.mcap");
  const mcap::WriteSummary w = write_sample(f, 50, 200);  // small chunks: many of them
  EXPECT_EQ(w.messages, 50u);
  EXPECT_GT(w.chunks, 5u);
  EXPECT_EQ(w.topic_messages.at("/a"), 25u);
  EXPECT_EQ(w.bytes, std::filesystem::file_size(f));
  int i = 0;
  const mcap::ReadSummary r = mcap::read_mcap_file(f, [&](const mcap::Channel& c, const mcap::MessageView& m) {
    EXPECT_EQ(c.topic, i % 2 ? "/b" : "/a");
    EXPECT_EQ(m.sequence, static_cast<std::uint32_t>(i));
    EXPECT_EQ(m.log_time_ns, 1000u + i);
    EXPECT_EQ(m.publish_time_ns, 900u + i);
    ASSERT_EQ(m.size, static_cast<std::size_t>(10 + i));
    EXPECT_EQ(m.data[0], static_cast<std::uint8_t>('a' + i % 26));
    ++i;
  });
  EXPECT_EQ(i, 50);
  EXPECT_EQ(r.profile, "ros2");
  EXPECT_EQ(r.messages, 50u);
  EXPECT_EQ(r.chunks, w.chunks);
  EXPECT_TRUE(r.has_summary);
  EXPECT_EQ(r.stated_messages, 50u);
  EXPECT_EQ(r.channels.at(1).metadata.at("offered_qos_profiles"), "- history: keep_last");
  EXPECT_EQ(r.schemas.at(1).data, "string data\n");
  EXPECT_EQ(r.metadata.at("cellsim").at("scenario"), "plane");
}

TEST(Mcap, TheFileHasTheSpecsFrameAndSummaryOffsetsThatPointAtTheirGroups) {
  const auto f = temp_file("frame.mcap");
  write_sample(f, 7, 1u << 20);
  const std::string b = slurp(f);
  ASSERT_GT(b.size(), 16u + 29u);
  EXPECT_EQ(b.substr(0, 8), std::string(mcap::kMagic, 8));
  EXPECT_EQ(b.substr(b.size() - 8), std::string(mcap::kMagic, 8));
  // the footer: summary start, summary offset start, summary CRC
  const std::size_t footer = b.size() - 8 - 29;
  EXPECT_EQ(static_cast<unsigned char>(b[footer]), mcap::kFooter);
  auto u64 = [&](std::size_t at) {
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(static_cast<unsigned char>(b[at + i])) << (8 * i);
    return v;
  };
  const std::uint64_t summary_start = u64(footer + 9), offsets_start = u64(footer + 17);
  ASSERT_LT(summary_start, offsets_start);
  EXPECT_EQ(static_cast<unsigned char>(b[summary_start]), mcap::kSchema);  // grouped by opcode, schemas first
  // each summary offset names a group that starts with a record of its opcode
  for (std::uint64_t at = offsets_start; at < footer; at += 9 + 17) {
    ASSERT_EQ(static_cast<unsigned char>(b[at]), mcap::kSummaryOffset);
    const auto op = static_cast<unsigned char>(b[at + 9]);
    EXPECT_EQ(static_cast<unsigned char>(b[u64(at + 10)]), op);
  }
}

// One line naming the file and an offset, as the issue asks of every malformed recording.
void expect_format_error(const std::string& bytes, const std::string& words) {
  try {
    mcap::read_mcap(bytes, "bad.mcap", nullptr);
    ADD_FAILURE() << "no error for a file that should have '" << words << "'";
  } catch (const mcap::FormatError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("bad.mcap: offset ", 0), 0u) << what;
    EXPECT_NE(what.find(words), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
}

TEST(Mcap, AMalformedFileIsOneLineNamingTheFileAndTheOffset) {
  const auto f = temp_file("good.mcap");
  write_sample(f, 9, 256);
  const std::string good = slurp(f);
  expect_format_error(good.substr(0, good.size() / 2), "");  // truncated, wherever the cut falls
  expect_format_error(good.substr(0, 17), "");
  expect_format_error("", "wrong magic");
  std::string magic = good;
  magic[1] = 'X';
  expect_format_error(magic, "wrong magic");
  // the header's length claims 4 GB, then past the file's end
  std::string huge = good;
  for (int i = 0; i < 8; ++i) huge[9 + i] = i == 4 ? '\x01' : '\0';
  expect_format_error(huge, "more than the limit");
  std::string past = good;
  past[9] = '\x7f';
  past[10] = '\x7f';
  expect_format_error(past, "past the file's end");
  std::string trailing = good + "x";
  expect_format_error(trailing, "");
}

// every byte cut, and every byte flipped, of a small file: an error or a clean read, no crash
TEST(Mcap, EveryTruncationAndEveryFlippedByteIsAnErrorOrAReadNeverACrash) {
  const auto f = temp_file("small.mcap");
  write_sample(f, 4, 64);
  const std::string good = slurp(f);
  int errors = 0;
  for (std::size_t n = 0; n < good.size(); ++n) {
    try {
      mcap::read_mcap(good.substr(0, n), "cut.mcap", nullptr);
    } catch (const mcap::FormatError&) {
      ++errors;
    }
  }
  EXPECT_EQ(errors, static_cast<int>(good.size()));  // no prefix of a file is a file
  for (std::size_t i = 0; i < good.size(); ++i) {
    std::string bad = good;
    bad[i] = static_cast<char>(bad[i] ^ 0xA5);
    try {
      mcap::read_mcap(bad, "flip.mcap", [](const mcap::Channel&, const mcap::MessageView&) {});
    } catch (const mcap::FormatError&) {
    }
  }
}

TEST(Mcap, AMessageOnAnUndefinedChannelAndAChannelOfAnUndefinedSchemaAreRefused) {
  std::string file = magic_and_header();
  std::string channel;
  mcap::put_u16(channel, 1);
  mcap::put_u16(channel, 7);  // schema 7: never defined
  mcap::put_string(channel, "/x");
  mcap::put_string(channel, "cdr");
  mcap::put_u32(channel, 0);
  expect_format_error(file + mcap::record(mcap::kChannel, channel), "never defined");
  std::string message;
  mcap::put_u16(message, 3);
  mcap::put_u32(message, 0);
  mcap::put_u64(message, 1);
  mcap::put_u64(message, 1);
  expect_format_error(file + mcap::record(mcap::kMessage, message), "channel 3, never defined");
}

TEST(Mcap, AChunkWhoseCrcDoesNotMatchIsRefused) {
  const auto f = temp_file("crc.mcap");
  write_sample(f, 3, 1u << 20);
  std::string b = slurp(f);
  // the one chunk's first message payload byte ('a'), flipped
  const std::size_t at = b.find(std::string(10, 'a'));
  ASSERT_NE(at, std::string::npos);
  b[at] = 'z';
  expect_format_error(b, "chunk CRC mismatch");
}

TEST(Mcap, AFifoIsRefusedNotWaitedOn) {
  const auto fifo = temp_file("fifo.mcap");
  std::filesystem::remove(fifo);
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_THROW(mcap::read_mcap_file(fifo, nullptr), std::runtime_error);
  EXPECT_THROW(mcap::Writer(fifo, {}), std::runtime_error);
}

// issue 40, item 1: a recording never replaces a file, and start-up that fails leaves none
TEST(Mcap, ARecordingNeverReplacesAFileAndIsPartialUntilClosed) {
  const auto f = temp_file("precious.mcap");
  { std::ofstream(f) << "precious"; }
  try {
    mcap::Writer w(f, {});
    ADD_FAILURE() << "an existing file was opened for writing";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("exists"), std::string::npos) << e.what();
  }
  EXPECT_EQ(slurp(f), "precious");
  EXPECT_THROW(mcap::Writer(std::filesystem::path(), {}), std::runtime_error);

  const auto g = temp_file("new.mcap");
  std::filesystem::remove(g);
  {
    mcap::Writer w(g, {});
    EXPECT_FALSE(std::filesystem::exists(g));
    EXPECT_TRUE(std::filesystem::exists(temp_file("new.mcap.partial")));
    // a second recorder given the same name is refused, and the first's file is untouched
    EXPECT_THROW(mcap::Writer(g, {}), std::runtime_error);
    const mcap::WriteSummary s = w.close();
    EXPECT_TRUE(s.complete);
    EXPECT_EQ(s.file, g);
    EXPECT_TRUE(s.problem.empty()) << s.problem;
  }
  EXPECT_TRUE(std::filesystem::exists(g));
  EXPECT_FALSE(std::filesystem::exists(temp_file("new.mcap.partial")));
  EXPECT_NO_THROW(mcap::read_mcap_file(g, nullptr));

  // a file that appears at the name while recording is not replaced: the recording stays .partial
  const auto h = temp_file("raced.mcap");
  std::filesystem::remove(h);
  mcap::Writer w(h, {});
  { std::ofstream(h) << "someone else's"; }
  const mcap::WriteSummary s = w.close();
  EXPECT_EQ(slurp(h), "someone else's");
  EXPECT_EQ(s.file, temp_file("raced.mcap.partial"));
  EXPECT_NE(s.problem.find("not replaced"), std::string::npos) << s.problem;
  EXPECT_NO_THROW(mcap::read_mcap_file(s.file, nullptr));

  // start-up failed: the partial file goes, nothing else does
  const auto a = temp_file("abandoned.mcap");
  std::filesystem::remove(a);
  mcap::Writer ab(a, {});
  ab.abandon();
  EXPECT_FALSE(std::filesystem::exists(a));
  EXPECT_FALSE(std::filesystem::exists(temp_file("abandoned.mcap.partial")));
}

// Writes `n` messages of 1000 bytes into chunks of 4 kB in a child that then dies without
// closing (SIGKILL's effect on the file), or with its file size limited to `fsize_limit` (a
// full disk) and raised again before close when `space_back`. Returns the child's file.
std::filesystem::path write_in_child(const std::string& name, int n, rlim_t fsize_limit, bool close, bool space_back,
                                     std::size_t payload_bytes = 1000, std::size_t chunk_bytes = 4096) {
  const auto f = temp_file(name);
  std::filesystem::remove(f);
  std::filesystem::remove(temp_file(name + ".partial"));
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::signal(SIGXFSZ, SIG_IGN);  // a write past the limit fails with EFBIG, as ENOSPC would
    mcap::WriterOptions o;
    o.chunk_bytes = chunk_bytes;
    mcap::Writer w(f, o);
    const auto s = w.add_schema("std_msgs/msg/String", "ros2msg", "string data\n");
    const auto c = w.add_channel(s, "/a", "cdr", {});
    rlimit lim{fsize_limit, RLIM_INFINITY};
    ::setrlimit(RLIMIT_FSIZE, &lim);
    const std::string payload(payload_bytes, 'p');
    int failures = 0;
    for (int i = 0; i < n; ++i) {
      try {
        w.write_message(c, static_cast<std::uint32_t>(i), 1000 + i, 1000 + i,
                        reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size());
      } catch (const std::runtime_error&) {
        ++failures;
      }
    }
    if (!close) ::_exit(0);  // no close, no destructor: what SIGKILL leaves
    // the record that says why still fits: the failed chunk was cut off the file
    if (failures > 0) w.add_metadata("recording_stopped", {{"reason", "full"}});
    // space back, or none at all: not even for the summary
    rlimit now{space_back ? RLIM_INFINITY : static_cast<rlim_t>(std::filesystem::file_size(w.partial_file())),
               RLIM_INFINITY};
    ::setrlimit(RLIMIT_FSIZE, &now);
    const mcap::WriteSummary done = w.close();
    // 10: a failure said; 11: a complete file; 12: a problem named
    ::_exit((failures > 0 ? 1 : 0) | (done.complete ? 2 : 0) | (done.problem.empty() ? 0 : 4) | 8);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  EXPECT_TRUE(WIFEXITED(status));
  last_child_code = WEXITSTATUS(status);
  return f;
}

TEST(Mcap, AKilledRecordingReadsAsTruncatedWithItsCompleteChunks) {
  const auto f = write_in_child("killed.mcap", 40, RLIM_INFINITY, false, false);
  const auto partial = temp_file("killed.mcap.partial");
  ASSERT_TRUE(std::filesystem::exists(partial));
  EXPECT_FALSE(std::filesystem::exists(f));
  try {
    mcap::read_mcap_file(partial, nullptr);
    ADD_FAILURE() << "a truncated file read as whole";
  } catch (const mcap::FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos) << e.what();
  }
  mcap::ReadLimits l;
  l.allow_truncated = true;
  std::uint32_t next = 0;
  const mcap::ReadSummary r = mcap::read_mcap_file(
      partial, [&](const mcap::Channel&, const mcap::MessageView& m) { EXPECT_EQ(m.sequence, next++); }, l);
  ASSERT_TRUE(r.truncated);
  EXPECT_NE(r.truncated->find("truncated"), std::string::npos);
  // four messages a 4 kB chunk: every complete one read, the open one (and the buffer) lost
  EXPECT_GE(r.chunks, 8u);
  EXPECT_EQ(r.messages, next);
  EXPECT_GE(r.messages, 32u);
  EXPECT_LT(r.messages, 40u);

  // killed with an open chunk partly on disk (its messages past the writer's 1 MB buffer):
  // the chunk's header still claims to run past the end, so it is a truncation, not garbage
  write_in_child("killed_mid_chunk.mcap", 25, RLIM_INFINITY, false, false, 300000, 4u << 20);
  const mcap::ReadSummary mid = mcap::read_mcap_file(temp_file("killed_mid_chunk.mcap.partial"), nullptr, l);
  ASSERT_TRUE(mid.truncated);
  EXPECT_NE(mid.truncated->find("runs past the file's end"), std::string::npos) << *mid.truncated;
  EXPECT_EQ(mid.chunks, 1u);   // 13 messages of 300 kB fill the first 4 MB chunk
  EXPECT_EQ(mid.messages, 13u);
}

TEST(Mcap, AFullDiskKeepsAReadableFileAndSaysWhy) {
  // space back before close: the file is whole, with the messages before the failure
  write_in_child("full_then_back.mcap", 60, 20000, true, true);
  EXPECT_EQ(last_child_code, 1 | 2 | 4 | 8);
  const mcap::ReadSummary back = mcap::read_mcap_file(temp_file("full_then_back.mcap"), nullptr);
  EXPECT_FALSE(back.truncated);
  EXPECT_GE(back.messages, 8u);
  EXPECT_LT(back.messages, 20u);
  EXPECT_EQ(back.stated_messages, back.messages);
  EXPECT_EQ(back.metadata.at("recording_stopped").at("reason"), "full");  // written after the failed write
  // full to the end: a file cut at its last complete record, read as truncated
  write_in_child("full.mcap", 60, 20000, true, false);
  EXPECT_EQ(last_child_code, 1 | 4 | 8);
  mcap::ReadLimits l;
  l.allow_truncated = true;
  const mcap::ReadSummary full = mcap::read_mcap_file(temp_file("full.mcap"), nullptr, l);
  ASSERT_TRUE(full.truncated);
  EXPECT_NE(full.truncated->find("ends before its footer"), std::string::npos) << *full.truncated;
  EXPECT_GE(full.messages, 8u);
}

// Issue 40, item 7: a file past the former 8 GB bound is read, streamed: a sparse 9 GB file of
// 45 attachments of 200 MB between a header and a summary (attachments are skipped, not read)
TEST(Mcap, AFileOverEightGigabytesIsStreamed) {
  const auto f = temp_file("large.mcap");
  std::filesystem::remove(f);
  {
    std::ofstream out(f, std::ios::binary);
    out << magic_and_header();
    const std::uint64_t len = 200ull << 20;
    for (int i = 0; i < 48; ++i) {
      std::string r(1, static_cast<char>(mcap::kAttachment));
      mcap::put_u64(r, len);
      out << r;
      out.seekp(static_cast<std::streamoff>(len), std::ios::cur);  // a hole: no disk
    }
    std::string end;
    mcap::put_u32(end, 0);
    out << mcap::record(mcap::kDataEnd, end);
    std::string footer(1, static_cast<char>(mcap::kFooter));
    mcap::put_u64(footer, 20);
    mcap::put_u64(footer, 0);
    mcap::put_u64(footer, 0);
    mcap::put_u32(footer, 0);
    out << footer << std::string(mcap::kMagic, 8);
  }
  ASSERT_GT(std::filesystem::file_size(f), 8ull << 30);
  const mcap::ReadSummary r = mcap::read_mcap_file(f, nullptr);
  EXPECT_FALSE(r.truncated);
  EXPECT_EQ(r.profile, "ros2");
  std::filesystem::remove(f);
}

TEST(Mcap, OpcodeZeroIsRefusedAtOnce) {
  std::string file = magic_and_header();
  expect_format_error(file + std::string(1 << 20, '\0'), "offset " + std::to_string(file.size()) + ": opcode 0");
}

TEST(Mcap, AnErrorInsideAChunkNamesTheRecordsOwnOffset) {
  std::string file = magic_and_header();
  std::string inner;
  inner += mcap::record(mcap::kMetadata, std::string(8, '\0'));  // not allowed inside a chunk
  std::string chunk;
  mcap::put_u64(chunk, 0);
  mcap::put_u64(chunk, 0);
  mcap::put_u64(chunk, inner.size());
  mcap::put_u32(chunk, 0);
  mcap::put_string(chunk, "");
  mcap::put_u64(chunk, inner.size());
  const std::size_t inner_at = file.size() + 9 + chunk.size();
  chunk += inner;
  file += mcap::record(mcap::kChunk, chunk);
  expect_format_error(file, "offset " + std::to_string(inner_at) + ": record of opcode 12 inside a chunk");
}

}  // namespace
