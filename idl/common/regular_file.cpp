#include "common/regular_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/vfs.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace common {
namespace {

// file systems whose "regular" files are the kernel's: reading them may block (/proc/kmsg),
// never end, or leak what the process may read but a remote peer must not
constexpr long kProcMagic = 0x9fa0, kSysfsMagic = 0x62656572, kDebugfsMagic = 0x64626720, kSecurityfsMagic = 0x73636673,
                 kTracefsMagic = 0x74726163, kCgroupMagic = 0x27e0eb, kCgroup2Magic = 0x63677270;

class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  int release() {
    const int f = fd_;
    fd_ = -1;
    return f;
  }

 private:
  int fd_;
};

[[noreturn]] void fail(const std::filesystem::path& file, const std::string& what) {
  throw FileError(file.string() + ": " + what);
}

std::string kind_of(mode_t m) {
  if (S_ISDIR(m)) return "a folder";
  if (S_ISFIFO(m)) return "a FIFO";
  if (S_ISSOCK(m)) return "a socket";
  if (S_ISCHR(m) || S_ISBLK(m)) return "a device";
  return "not a regular file";
}

// Opens and checks; returns the open descriptor and the size.
int open_checked(const std::filesystem::path& file, std::uintmax_t max_bytes, const std::string& what,
                 std::uintmax_t& size) {
  // O_NONBLOCK: opening a FIFO for reading would wait for a writer; O_NOCTTY: a terminal
  // named here must not become ours
  const int fd = ::open(file.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) {
    const int e = errno;
    if (e == ENOENT || e == ENOTDIR) fail(file, what + " not found");
    fail(file, "cannot open " + what + ": " + std::strerror(e));
  }
  Fd guard(fd);
  struct stat st {};
  if (::fstat(fd, &st) != 0) fail(file, "cannot read " + what + ": " + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) fail(file, what + " is " + kind_of(st.st_mode) + ", not a regular file");
  struct statfs fs {};
  if (::fstatfs(fd, &fs) == 0) {
    const long t = static_cast<long>(fs.f_type);
    if (t == kProcMagic || t == kSysfsMagic || t == kDebugfsMagic || t == kSecurityfsMagic || t == kTracefsMagic ||
        t == kCgroupMagic || t == kCgroup2Magic)
      fail(file, what + " is a kernel file (/proc, /sys), not a regular file");
  }
  if (st.st_size < 0 || static_cast<std::uintmax_t>(st.st_size) > max_bytes)
    fail(file, what + " is " + std::to_string(static_cast<long long>(st.st_size)) + " bytes, more than the limit of " +
                   std::to_string(max_bytes));
  size = static_cast<std::uintmax_t>(st.st_size);
  // a regular file never blocks, but clear the flag so that reads are ordinary ones
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
  return guard.release();
}

}  // namespace

std::string read_regular_file(const std::filesystem::path& file, std::uintmax_t max_bytes, const std::string& what) {
  std::uintmax_t size = 0;
  Fd fd(open_checked(file, max_bytes, what, size));
  std::string data(static_cast<std::size_t>(size), '\0');
  std::size_t got = 0;
  // at most the size fstat gave: a file that grows meanwhile is read as it was
  while (got < data.size()) {
    const ssize_t n = ::read(fd.get(), data.data() + got, data.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) fail(file, "cannot read " + what + ": " + std::strerror(errno));
    if (n == 0) break;
    got += static_cast<std::size_t>(n);
  }
  data.resize(got);
  return data;
}

int open_regular_file(const std::filesystem::path& file, std::uintmax_t max_bytes, const std::string& what,
                      std::uintmax_t& size) {
  return open_checked(file, max_bytes, what, size);
}

std::uintmax_t check_regular_file(const std::filesystem::path& file, std::uintmax_t max_bytes,
                                  const std::string& what) {
  std::uintmax_t size = 0;
  Fd fd(open_checked(file, max_bytes, what, size));
  return size;
}

}  // namespace common
