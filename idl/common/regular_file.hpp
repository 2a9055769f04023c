// Reading a file that a user or a remote peer named, without ever blocking on it: the file is
// opened non-blocking and must then be a regular file on a disk file system (not a FIFO, a
// device, a folder, or a /proc or /sys file, which report themselves as regular but may block
// or read without end), and no larger than a bound given by the caller (issue 18, item 9).
// A leaf library (std and POSIX only): every reader of the project opens files through it.
#pragma once

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>

namespace common {

// A file that cannot be read as asked. what() is one line: "<file>: <what is wrong>".
class FileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The whole content of `file`, at most `max_bytes`. `what` names the kind of file in messages
// ("scenario", "mesh file"). Throws FileError.
std::string read_regular_file(const std::filesystem::path& file, std::uintmax_t max_bytes,
                              const std::string& what = "file");

// The same checks, and the file left open for reading (a reader that streams a file larger
// than memory: a recording). Returns the descriptor, which the caller closes; `size` is the
// file's size as fstat gave it.
int open_regular_file(const std::filesystem::path& file, std::uintmax_t max_bytes, const std::string& what,
                      std::uintmax_t& size);

// The same checks without keeping the bytes, for a library that opens the path itself; returns
// the file's size.
std::uintmax_t check_regular_file(const std::filesystem::path& file, std::uintmax_t max_bytes,
                                  const std::string& what = "file");

}  // namespace common
