#include "common/output_file.hpp"

#include "common/strict_yaml.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ext/stdio_filebuf.h>
#include <map>
#include <mutex>
#include <set>
#include <sstream>

namespace common {
namespace {

// the list holds a name a line; 8 MiB is some 300 000 names, far more than any run writes, and
// bounds what a list planted in a folder can make a writer read
constexpr std::uintmax_t kMaxListBytes = 8u << 20;

// a name from a folder's listing (servo decode --json-dir) may hold a line break: the message
// stays one line (printable: its bytes past ASCII as \xNN too)
[[noreturn]] void fail(const std::filesystem::path& file, const std::string& what) {
  throw FileError(printable(file.string(), 1024) + ": " + what);
}

std::filesystem::path folder_of(const std::filesystem::path& file) {
  return file.has_parent_path() ? file.parent_path() : std::filesystem::path(".");
}

std::string kind_of(mode_t m) {
  if (S_ISLNK(m)) return "a symbolic link";
  if (S_ISDIR(m)) return "a folder";
  if (S_ISFIFO(m)) return "a FIFO";
  if (S_ISSOCK(m)) return "a socket";
  if (S_ISCHR(m) || S_ISBLK(m)) return "a device";
  return "not a regular file";
}

// The names each folder's list holds, as far as this process knows: read once, and again when
// a name is missing (another process may have written it since).
class WrittenLists {
 public:
  bool listed(const std::filesystem::path& dir, const std::string& name) {
    std::lock_guard<std::mutex> lock(mutex_);
    auto& names = known_[key(dir)];
    if (names.count(name)) return true;
    names = read(dir);
    return names.count(name) > 0;
  }

  void record(const std::filesystem::path& dir, const std::string& name) {
    std::lock_guard<std::mutex> lock(mutex_);
    auto& names = known_[key(dir)];
    if (names.count(name)) return;
    const std::filesystem::path list = dir / kWrittenList;
    const int fd = ::open(list.c_str(), O_WRONLY | O_APPEND | O_CREAT | O_NOFOLLOW | O_CLOEXEC | O_NOCTTY | O_NONBLOCK, 0644);
    if (fd < 0) fail(list, std::string("cannot keep the list of the files written here: ") + std::strerror(errno));
    struct stat st {};
    const bool regular = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
    const std::string line = name + "\n";
    // O_APPEND: one write of a short line lands whole, beside the lines of other writers
    const bool written = regular && ::write(fd, line.data(), line.size()) == static_cast<ssize_t>(line.size());
    ::close(fd);
    if (!regular) fail(list, "the list of the files written here is " + kind_of(st.st_mode) + ", not a regular file");
    if (!written) fail(list, "cannot add to the list of the files written here");
    names.insert(name);
  }

 private:
  static std::string key(const std::filesystem::path& dir) {
    std::error_code ec;
    const auto abs = std::filesystem::absolute(dir, ec);
    return (ec ? dir : abs).lexically_normal().string();
  }

  static std::set<std::string> read(const std::filesystem::path& dir) {
    const std::filesystem::path list = dir / kWrittenList;
    struct stat st {};
    if (::lstat(list.c_str(), &st) != 0) return {};
    if (S_ISLNK(st.st_mode)) fail(list, "the list of the files written here is a symbolic link; not read");
    std::istringstream lines(read_regular_file(list, kMaxListBytes, "list of the files written here"));
    std::set<std::string> names;
    for (std::string line; std::getline(lines, line);)
      if (!line.empty()) names.insert(line);
    return names;
  }

  std::mutex mutex_;
  std::map<std::string, std::set<std::string>> known_;
};

WrittenLists& written_lists() {
  static WrittenLists lists;
  return lists;
}

void check_name(const std::filesystem::path& file, const std::string& what) {
  if (file.empty()) throw FileError("the " + what + " file's name is empty");
  const std::string name = file.filename().string();
  if (name.empty() || name == "." || name == "..") fail(file, "names a folder; give the " + what + " a file name");
  if (name == kWrittenList) fail(file, "is the list of the files written here; not written as a " + what);
  if (name.find('\n') != std::string::npos) fail(file, "a file name with a line break is not written");
}

// What is at `file` already may be written over: a regular file the folder's list names.
void check_existing(const std::filesystem::path& file, const struct stat& st) {
  if (!S_ISREG(st.st_mode)) fail(file, "is " + kind_of(st.st_mode) + "; not written through (move it away)");
  if (!written_lists().listed(folder_of(file), file.filename().string()))
    fail(file, "exists and was not written here by this project (" + std::string(kWrittenList) +
                   " does not list it); not overwritten: move it away or name another folder");
}

// The open descriptor of `file` for writing, emptied, under the rule of the header.
int claim(const std::filesystem::path& file, const std::string& what) {
  check_name(file, what);
  const std::string name = file.filename().string();
  const std::filesystem::path dir = folder_of(file);
  constexpr int kFlags = O_WRONLY | O_NOFOLLOW | O_CLOEXEC | O_NOCTTY | O_NONBLOCK;
  int fd = ::open(file.c_str(), kFlags | O_CREAT | O_EXCL, 0644);
  const bool created = fd >= 0;
  if (fd < 0 && errno != EEXIST) {
    const int e = errno;
    if (e == ENOENT || e == ENOTDIR) fail(file, "cannot create the " + what + ": its folder does not exist");
    fail(file, "cannot create the " + what + ": " + std::strerror(e));
  }
  if (fd < 0) {
    struct stat st {};
    if (::lstat(file.c_str(), &st) != 0) fail(file, std::string("cannot read what is there: ") + std::strerror(errno));
    check_existing(file, st);
    fd = ::open(file.c_str(), kFlags);
    if (fd < 0) fail(file, "cannot open the " + what + ": " + std::strerror(errno));
    struct stat now {};
    if (::fstat(fd, &now) == 0 && S_ISREG(now.st_mode) && now.st_nlink > 1) {
      // another name for the same bytes (a hard link, a snapshot made with cp -al): emptying
      // ours would empty that one
      ::close(fd);
      fail(file, "has other names (hard links); not written over: move it away");
    }
    if (::fstat(fd, &now) != 0 || !S_ISREG(now.st_mode) || ::ftruncate(fd, 0) != 0) {
      ::close(fd);
      fail(file, "cannot write the " + what + " over the last one");
    }
  }
  try {
    written_lists().record(dir, name);
  } catch (...) {
    ::close(fd);
    if (created) ::unlink(file.c_str());  // ours, made above with O_EXCL and still empty
    throw;
  }
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
  return fd;
}

}  // namespace

void make_output_folder(const std::filesystem::path& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir))
    fail(dir, "cannot make the output folder: " + (ec ? ec.message() : std::string("it is a file")));
}

void check_output_file(const std::filesystem::path& file, const std::string& what) {
  check_name(file, what);
  struct stat st {};
  if (::lstat(file.c_str(), &st) == 0) check_existing(file, st);
}

void write_output_file(const std::filesystem::path& file, std::string_view bytes, const std::string& what) {
  const int fd = claim(file, what);
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int e = errno;
      ::close(fd);
      fail(file, "cannot write the " + what + ": " + std::strerror(e));
    }
    done += static_cast<std::size_t>(n);
  }
  if (::close(fd) != 0) fail(file, "cannot write the " + what + ": " + std::strerror(errno));
}

struct OutputStream::Buffer {
  explicit Buffer(int fd) : buf(fd, std::ios::out | std::ios::binary) {}
  __gnu_cxx::stdio_filebuf<char> buf;  // closes the descriptor when it goes
};

OutputStream::OutputStream() : std::ostream(nullptr) {}

OutputStream::~OutputStream() {
  try {
    close();
  } catch (const FileError&) {
    // a destructor runs on the paths an error already took: that error is the one said
  }
}

void OutputStream::open(const std::filesystem::path& file, const std::string& what) {
  close();
  buffer_ = std::make_unique<Buffer>(claim(file, what));
  file_ = file;
  what_ = what;
  rdbuf(&buffer_->buf);
  clear();
}

bool OutputStream::is_open() const { return buffer_ != nullptr; }

void OutputStream::close() {
  if (!buffer_) return;
  errno = 0;
  flush();
  // stdio_filebuf::close returns null when the last write or the close itself failed
  const bool written = !fail() && buffer_->buf.close() != nullptr;
  const int e = errno;
  rdbuf(nullptr);
  buffer_.reset();
  if (!written)
    throw FileError(printable(file_.string(), 1024) + ": cannot write the " + what_ + ": " +
                    (e ? std::strerror(e) : "a write failed"));
}

}  // namespace common
