#include "servo/pattern/pattern_file.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace pattern {
namespace {

std::filesystem::path write_temp(const std::string& name, const std::string& text) {
  const auto path = std::filesystem::temp_directory_path() / ("pattern_file_test_" + name);
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const PatternFileError& e) {
    return e.what();
  }
  return "";
}

TEST(PatternFile, RoundTrips) {
  const MArray a{2, 3, 3, {0, 1, 2, 2, 1, 0}};
  const auto path = write_temp("rt.txt", format_marray(a));
  EXPECT_EQ(read_marray(path, 3), a);
  EXPECT_EQ(format_marray(a), "012\n210\n");
}

TEST(PatternFile, WrongDigitNamesFileLineAndColumn) {
  const auto path = write_temp("digit.txt", "0120\n01x2\n");
  const std::string e = error_of([&] { read_marray(path); });
  EXPECT_NE(e.find(path.string() + ":2: wrong digit 'x' at column 3"), std::string::npos) << e;
  EXPECT_EQ(e.find('\n'), std::string::npos);
}

TEST(PatternFile, DigitOutsideTheAlphabetIsWrong) {
  const auto path = write_temp("alphabet.txt", "012\n013\n");
  const std::string e = error_of([&] { read_marray(path, 3); });
  EXPECT_NE(e.find(":2: wrong digit '3'"), std::string::npos) << e;
}

TEST(PatternFile, RaggedRowsAreRejected) {
  const auto path = write_temp("ragged.txt", "0120\n012\n");
  const std::string e = error_of([&] { read_marray(path); });
  EXPECT_NE(e.find(":2: ragged rows: this row has 3 spots, the first has 4"), std::string::npos) << e;
}

TEST(PatternFile, RepeatedWindowIsRejectedByLoadPattern) {
  // rows 0-2 and rows 3-5 are identical: every window repeats
  const auto path = write_temp("repeat.txt", "012\n120\n201\n012\n120\n201\n");
  EXPECT_NO_THROW(read_marray(path));
  const std::string e = error_of([&] { load_pattern(path, {3, 3}); });
  EXPECT_NE(e.find(path.string() + ": repeated window"), std::string::npos) << e;
  EXPECT_NE(e.find("(1, 1) and (4, 1)"), std::string::npos) << e;
}

TEST(PatternFile, MissingAndEmptyFiles) {
  EXPECT_NE(error_of([] { read_marray("/nonexistent/p.txt"); }).find("/nonexistent/p.txt: pattern file not found"),
            std::string::npos);
  const auto path = write_temp("empty.txt", "");
  EXPECT_NE(error_of([&] { read_marray(path); }).find("empty pattern file"), std::string::npos);
}

TEST(PatternFile, CommittedPatternLoads) {
  const MArray a = load_pattern(std::string(CELL_SOURCE_DIR) + "/servo/pattern/data/marray_20x20_k3_w3.txt", {3, 3}, 3);
  EXPECT_EQ(a.rows, 20);
  EXPECT_EQ(a.cols, 20);
}

}  // namespace
}  // namespace pattern
