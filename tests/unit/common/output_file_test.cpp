// Writing outputs (idl/common/output_file): a new file is written and listed; a file the list
// names is written over; a user's file of the same name, a symbolic link, a FIFO or a folder in
// its place is refused in one line naming it and is left as it was.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>
#include <vector>

#include "common/output_file.hpp"

namespace {

namespace fs = std::filesystem;

class OutputFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("output_file_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  static std::string slurp(const fs::path& f) {
    std::ifstream in(f, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }
  static void plant(const fs::path& f, const std::string& text) { std::ofstream(f, std::ios::binary) << text; }

  // the error `write` throws: one line that names `file`
  template <typename Write>
  static std::string refusal(const fs::path& file, Write write) {
    try {
      write();
    } catch (const common::FileError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
      EXPECT_NE(what.find(file.string()), std::string::npos) << what;
      return what;
    }
    ADD_FAILURE() << file << ": written, not refused";
    return "";
  }

  fs::path dir_;
};

TEST_F(OutputFileTest, ANewFileIsWrittenAndListedAndTheNextRunWritesOverIt) {
  const fs::path f = dir_ / "trace.csv";
  common::write_output_file(f, "first\n");
  EXPECT_EQ(slurp(f), "first\n");
  EXPECT_EQ(slurp(dir_ / common::kWrittenList), "trace.csv\n");
  common::write_output_file(f, "2\n");
  EXPECT_EQ(slurp(f), "2\n");  // emptied first: nothing of the longer first run is left
  EXPECT_EQ(slurp(dir_ / common::kWrittenList), "trace.csv\n");  // listed once
  EXPECT_NO_THROW(common::check_output_file(f));
}

TEST_F(OutputFileTest, AUsersFileOfOurNameIsRefusedAndKept) {
  const fs::path f = dir_ / "summary.md";
  plant(f, "my notes\n");
  EXPECT_NE(refusal(f, [&] { common::write_output_file(f, "ours"); }).find("not overwritten"), std::string::npos);
  refusal(f, [&] { common::check_output_file(f); });
  refusal(f, [&] { common::OutputStream s; s.open(f); });
  EXPECT_EQ(slurp(f), "my notes\n");
}

TEST_F(OutputFileTest, ALinkIsNeverWrittenThroughEvenWhenListed) {
  const fs::path victim = dir_ / "victim.txt";
  plant(victim, "precious\n");
  const fs::path out = dir_ / "out";
  fs::create_directories(out);
  plant(out / common::kWrittenList, "sweep.csv\n");  // a list that claims the name
  fs::create_symlink(victim, out / "sweep.csv");
  EXPECT_NE(refusal(out / "sweep.csv", [&] { common::write_output_file(out / "sweep.csv", "x"); })
                .find("symbolic link"),
            std::string::npos);
  EXPECT_EQ(slurp(victim), "precious\n");
  // nor a hard link: the name is listed and a regular file, but its bytes are another file's too
  fs::remove(out / "sweep.csv");
  fs::create_hard_link(victim, out / "sweep.csv");
  EXPECT_NE(refusal(out / "sweep.csv", [&] { common::write_output_file(out / "sweep.csv", "x"); }).find("hard links"),
            std::string::npos);
  EXPECT_EQ(slurp(victim), "precious\n");
}

TEST_F(OutputFileTest, AFifoAFolderAndTheListItselfAreRefused) {
  ASSERT_EQ(::mkfifo((dir_ / "fifo.png").c_str(), 0644), 0);
  EXPECT_NE(refusal(dir_ / "fifo.png", [&] { common::write_output_file(dir_ / "fifo.png", "x"); }).find("a FIFO"),
            std::string::npos);
  fs::create_directories(dir_ / "trace.csv");
  EXPECT_NE(refusal(dir_ / "trace.csv", [&] { common::write_output_file(dir_ / "trace.csv", "x"); }).find("a folder"),
            std::string::npos);
  refusal(dir_ / common::kWrittenList, [&] { common::write_output_file(dir_ / common::kWrittenList, "x"); });
  refusal(dir_ / "missing" / "a.csv", [&] { common::write_output_file(dir_ / "missing" / "a.csv", "x"); });
  try {  // a name with a line break (an image's in a folder, servo decode --json-dir) is said on one line
    common::write_output_file(dir_ / "a\nb.json", "x");
    ADD_FAILURE() << "a name with a line break was written";
  } catch (const common::FileError& e) {
    EXPECT_NE(std::string(e.what()).find("a\\x0ab.json"), std::string::npos) << e.what();
  }
}

TEST_F(OutputFileTest, AListThatIsALinkIsNeitherReadNorWritten) {
  plant(dir_ / "elsewhere", "");
  fs::create_symlink(dir_ / "elsewhere", dir_ / common::kWrittenList);
  refusal(dir_ / common::kWrittenList, [&] { common::write_output_file(dir_ / "new.csv", "x"); });
  EXPECT_EQ(slurp(dir_ / "elsewhere"), "");
  EXPECT_FALSE(fs::exists(dir_ / "new.csv"));  // the file it had made is taken back
}

TEST_F(OutputFileTest, AStreamWritesAsItGoesAndAFolderIsMadeForIt) {
  const fs::path sub = dir_ / "a" / "b";
  common::make_output_folder(sub);
  common::OutputStream s;
  s.open(sub / "features.jsonl");
  ASSERT_TRUE(s.is_open());
  s << "{\"k\": 1}\n" << std::flush;
  EXPECT_EQ(slurp(sub / "features.jsonl"), "{\"k\": 1}\n");
  s.close();
  EXPECT_FALSE(s.is_open());
  plant(dir_ / "file", "");
  refusal(dir_ / "file", [&] { common::make_output_folder(dir_ / "file"); });
}

// A stream's failed write is said when it is closed, not left as a short file that looks whole:
// in a child process (the limit is the process's) whose file size limit the stream passes.
TEST_F(OutputFileTest, AStreamThatCouldNotWriteSaysSoWhenClosed) {
  const fs::path f = dir_ / "trace.csv";
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::signal(SIGXFSZ, SIG_IGN);  // past the limit a write fails with EFBIG, as ENOSPC would
    rlimit lim{4096, RLIM_INFINITY};
    ::setrlimit(RLIMIT_FSIZE, &lim);
    common::OutputStream s;
    s.open(f, "trace");
    for (int i = 0; i < 1000; ++i) s << "0.000000,1.000000,2.000000\n";
    try {
      s.close();
    } catch (const common::FileError& e) {
      const std::string what = e.what();
      ::_exit(what.find("trace.csv: cannot write the trace") != std::string::npos && what.find('\n') == std::string::npos
                  ? 3
                  : 4);
    }
    ::_exit(5);  // closed as if whole
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 3) << "4: the message, 5: no error";
  EXPECT_LE(fs::file_size(f), 4096u);
}

TEST_F(OutputFileTest, ThreadsWritingIntoOneFolderEachFindTheirFileListed) {
  std::vector<std::thread> threads;
  for (int t = 0; t < 8; ++t)
    threads.emplace_back([&, t] {
      for (int k = 0; k < 20; ++k) common::write_output_file(dir_ / ("f" + std::to_string(t * 100 + k)), "x");
    });
  for (auto& t : threads) t.join();
  std::istringstream list(slurp(dir_ / common::kWrittenList));
  int lines = 0;
  for (std::string l; std::getline(list, l);) ++lines;
  EXPECT_EQ(lines, 160);
}

}  // namespace
