// The shared-memory files a process killed with SIGKILL leaves behind are removed, and nothing a
// live process holds or is creating (stop 38: each leftover segment is 65 MB of memory).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>

#include "dds/participant.hpp"

namespace cell_dds {
namespace {

namespace fs = std::filesystem;

class OrphanedShm : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("cell_shm_cleanup_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A file as Fast DDS makes it, with its lock file; `age` back in time.
  void make(const std::string& name, std::chrono::seconds age = std::chrono::seconds(600)) {
    for (const std::string& f : {name, name + "_el"}) {
      std::ofstream(dir_ / f) << std::string(4096, '\0');
      fs::last_write_time(dir_ / f, fs::file_time_type::clock::now() - age);
    }
  }
  bool exists(const std::string& name) const { return fs::exists(dir_ / name); }
  static bool has(const std::vector<std::string>& v, const std::string& s) {
    return std::find(v.begin(), v.end(), s) != v.end();
  }

  fs::path dir_;
};

TEST_F(OrphanedShm, SegmentsAndPortsOfDeadProcessesAreRemovedWithTheirLocksAndSemaphores) {
  make("fastrtps_0123456789abcdef");
  make("fastrtps_port7411");
  std::ofstream(dir_ / "sem.fastrtps_port7411_mutex") << "x";
  const auto removed = remove_orphaned_shm_files(dir_, std::chrono::seconds(60));
  EXPECT_TRUE(has(removed, "fastrtps_0123456789abcdef"));
  EXPECT_TRUE(has(removed, "fastrtps_port7411"));
  EXPECT_EQ(removed.size(), 2u);
  for (const char* f : {"fastrtps_0123456789abcdef", "fastrtps_0123456789abcdef_el", "fastrtps_port7411",
                        "fastrtps_port7411_el", "sem.fastrtps_port7411_mutex"})
    EXPECT_FALSE(exists(f)) << f;
}

TEST_F(OrphanedShm, AFileWhoseOwnerHoldsItsLockIsKept) {
  make("fastrtps_00000000feedface");
  // Fast DDS's owner holds flock on <name>_el while it lives
  const int fd = open((dir_ / "fastrtps_00000000feedface_el").c_str(), O_RDONLY);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(flock(fd, LOCK_EX | LOCK_NB), 0);
  EXPECT_TRUE(remove_orphaned_shm_files(dir_, std::chrono::seconds(60)).empty());
  EXPECT_TRUE(exists("fastrtps_00000000feedface"));
  close(fd);
  // the owner gone, the same file goes
  EXPECT_EQ(remove_orphaned_shm_files(dir_, std::chrono::seconds(60)).size(), 1u);
}

TEST_F(OrphanedShm, AFileSomeProcessMapsIsKept) {
  make("fastrtps_port7413");
  const int fd = open((dir_ / "fastrtps_port7413").c_str(), O_RDONLY);
  ASSERT_GE(fd, 0);
  void* m = mmap(nullptr, 4096, PROT_READ, MAP_SHARED, fd, 0);
  ASSERT_NE(m, MAP_FAILED);
  close(fd);
  EXPECT_TRUE(remove_orphaned_shm_files(dir_, std::chrono::seconds(60)).empty());
  EXPECT_TRUE(exists("fastrtps_port7413"));
  munmap(m, 4096);
}

TEST_F(OrphanedShm, AFileBeingCreatedIsKept) {
  // neither mapped nor locked yet while its process creates it: only age tells
  make("fastrtps_0000000000000001", std::chrono::seconds(0));
  EXPECT_TRUE(remove_orphaned_shm_files(dir_, std::chrono::seconds(60)).empty());
  EXPECT_TRUE(exists("fastrtps_0000000000000001"));
}

TEST_F(OrphanedShm, OnlyFastDdsNamesAreTouched) {
  for (const char* n : {"fastrtps_port", "fastrtps_port74x1", "fastrtps_0123", "fastrtps_0123456789ABCDEF",
                        "fastrtps_0123456789abcdefg", "something_else", "fastrtps_port7411_el"})
    make(n);
  EXPECT_TRUE(remove_orphaned_shm_files(dir_, std::chrono::seconds(60)).empty());
  EXPECT_TRUE(exists("something_else"));
  EXPECT_TRUE(exists("fastrtps_0123456789ABCDEF"));
}

TEST_F(OrphanedShm, AFifoPlantedAsALockNeitherHangsNorLetsTheFileGo) {
  std::ofstream(dir_ / "fastrtps_port7415") << "x";
  fs::last_write_time(dir_ / "fastrtps_port7415", fs::file_time_type::clock::now() - std::chrono::seconds(600));
  ASSERT_EQ(mkfifo((dir_ / "fastrtps_port7415_el").c_str(), 0600), 0);
  EXPECT_TRUE(remove_orphaned_shm_files(dir_, std::chrono::seconds(60)).empty());
  EXPECT_TRUE(exists("fastrtps_port7415"));
}

TEST(ShmSize, RoomForTwiceTheBuffersAndOneMessageAndAnEighthOfASmallShmAtMost) {
  const std::uint64_t kMessage = 65'536, kSlack = 1u << 20;
  // a machine's /dev/shm (half its memory): Fast DDS's 512 buffers, 2 x 512 + 1 messages
  const ShmSize big = shm_size_for(12ull << 30);
  EXPECT_EQ(big.buffers, 512u);
  EXPECT_EQ(big.segment_bytes, (2 * 512 + 1) * kMessage + kSlack);
  // Docker's default 64 MB: an eighth, and the rule kept with fewer buffers
  const ShmSize docker = shm_size_for(64ull << 20);
  EXPECT_LE(docker.segment_bytes, (64ull << 20) / 8);
  EXPECT_GE(docker.buffers, 16u);
  EXPECT_EQ(docker.segment_bytes, (2 * docker.buffers + 1) * kMessage + kSlack);
  // almost nothing free: 16 buffers still (Fast DDS then reports the segment it cannot make)
  EXPECT_EQ(shm_size_for(0).buffers, 16u);
}

// Issue 40, item 9: of 11 entries named like Fast DDS files, each case here was once removed.
TEST_F(OrphanedShm, OnlyThisUsersFreeRegularFilesGo) {
  const auto old = [&](const std::string& n) {
    fs::last_write_time(dir_ / n, fs::file_time_type::clock::now() - std::chrono::seconds(600));
  };
  // an empty folder and a FIFO under a port's name
  fs::create_directory(dir_ / "fastrtps_0123456789abcde0");
  ASSERT_EQ(mkfifo((dir_ / "fastrtps_port7420").c_str(), 0600), 0);
  old("fastrtps_port7420");
  std::ofstream(dir_ / "fastrtps_port7420_el") << "x";
  // a file this process holds open, not mapped
  make("fastrtps_port7421");
  const int held = open((dir_ / "fastrtps_port7421").c_str(), O_RDONLY);
  ASSERT_GE(held, 0);
  // a port whose lock is a link to a lock this process holds
  make("fastrtps_port7422");
  fs::remove(dir_ / "fastrtps_port7422_el");
  std::ofstream(dir_ / "real_lock") << "x";
  const int lock = open((dir_ / "real_lock").c_str(), O_RDONLY);
  ASSERT_EQ(flock(lock, LOCK_EX | LOCK_NB), 0);
  fs::create_symlink(dir_ / "real_lock", dir_ / "fastrtps_port7422_el");
  // an orphaned port whose semaphore is a folder: the port goes, the folder stays
  make("fastrtps_port7423");
  fs::create_directory(dir_ / "sem.fastrtps_port7423_mutex");
  // a killed process's data-sharing pool goes; one this process holds stays
  const std::string pool = "fast_datasharing_01.0f.78.fd.07.25.f5.b2.01.00.00.00_0.0.6.3";
  const std::string live_pool = "fast_datasharing_01.0f.78.fd.07.25.f5.b3.01.00.00.00_0.0.6.3";
  for (const auto& n : {pool, live_pool}) {
    std::ofstream(dir_ / n) << std::string(1676, '\0');
    old(n);
  }
  const int pool_fd = open((dir_ / live_pool).c_str(), O_RDONLY);
  ASSERT_GE(pool_fd, 0);
  // another user's file (root can make one; elsewhere that case is not made)
  make("fastrtps_port7424");
  const bool others = chown((dir_ / "fastrtps_port7424").c_str(), 65534, 65534) == 0;

  const auto removed = remove_orphaned_shm_files(dir_, std::chrono::seconds(60));
  close(held);
  close(lock);
  close(pool_fd);
  for (const char* kept : {"fastrtps_0123456789abcde0", "fastrtps_port7420", "fastrtps_port7421",
                           "fastrtps_port7421_el", "fastrtps_port7422", "fastrtps_port7422_el", "real_lock",
                           "sem.fastrtps_port7423_mutex"})
    EXPECT_TRUE(exists(kept)) << kept << " was removed";
  EXPECT_TRUE(exists(live_pool));
  EXPECT_TRUE(fs::is_directory(dir_ / "fastrtps_0123456789abcde0"));
  EXPECT_FALSE(exists("fastrtps_port7423"));
  EXPECT_FALSE(exists(pool));
  if (others) {
    EXPECT_TRUE(exists("fastrtps_port7424")) << "another user's file was removed";
  }
  EXPECT_EQ(removed.size(), others ? 2u : 3u);
}

}  // namespace
}  // namespace cell_dds
