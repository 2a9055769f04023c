// Writing a file the user named, or one of ours in a folder the user named, without destroying
// what is not ours. Every writer of the project opens its files through here (the reading side
// is regular_file.hpp).
//
// The rule: a program of this project writes a file only if the file is new, or if the list
// `.cell-written` in its folder says that a program of this project wrote it there. That list is
// kept by the writers themselves, a name a line. So a run into the folder of the last run writes
// over the last run's files, as a user expects, while a file of the user's that happens to have
// one of our names (summary.md, trace.csv) is refused in one line and kept. A symbolic link and
// anything that is not a regular file are never written through: a link planted in an output
// folder would otherwise make a run destroy the file it points to.
#pragma once

#include <filesystem>
#include <memory>
#include <ostream>
#include <string>
#include <string_view>

#include "common/regular_file.hpp"

namespace common {

// The name of the list of the files written, one in each folder written into.
inline constexpr const char* kWrittenList = ".cell-written";

// Creates `dir` and its parents for output. Throws FileError naming it if it, or one of its
// parents, is a file.
void make_output_folder(const std::filesystem::path& dir);

// Throws FileError as write_output_file would if `file` may not be written, without writing it:
// a long run checks the files it writes at its end before it starts.
void check_output_file(const std::filesystem::path& file, const std::string& what = "file");

// Writes `bytes` as `file` under the rule above. `what` names the kind of file in messages
// ("trace", "image"). Throws FileError, one line naming the file.
void write_output_file(const std::filesystem::path& file, std::string_view bytes, const std::string& what = "file");

// A file written as a run goes (a trace, a features log), opened under the rule above. close()
// says a write that failed (a full disk, a file size limit) instead of leaving a short file
// that looks whole; the destructor closes without a word, for the paths an error already took.
class OutputStream : public std::ostream {
 public:
  OutputStream();
  ~OutputStream() override;
  OutputStream(const OutputStream&) = delete;
  OutputStream& operator=(const OutputStream&) = delete;

  // Throws FileError, one line naming the file.
  void open(const std::filesystem::path& file, const std::string& what = "file");
  bool is_open() const;
  // Flushes and closes. Throws FileError, one line naming the file, if any write failed.
  void close();

 private:
  struct Buffer;
  std::unique_ptr<Buffer> buffer_;
  std::filesystem::path file_;
  std::string what_;
};

}  // namespace common
