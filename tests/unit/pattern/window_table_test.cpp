#include "servo/pattern/window_table.hpp"

#include <gtest/gtest.h>

#include "servo/pattern/pattern_file.hpp"

namespace pattern {
namespace {

TEST(WindowTable, EveryWindowMapsToItsCentre) {
  const MArray a = *generate_marray(GenerationOptions{}).array;
  const WindowTable table(a, {3, 3});
  EXPECT_EQ(table.size(), 18u * 18u);
  std::uint8_t w[9];
  for (int r = 1; r < 19; ++r)
    for (int c = 1; c < 19; ++c) {
      for (int i = 0; i < 9; ++i) w[i] = a.at(r - 1 + i / 3, c - 1 + i % 3);
      const auto id = table.find(w);
      ASSERT_TRUE(id);
      EXPECT_EQ(*id, (SpotId{r, c}));
    }
}

TEST(WindowTable, AbsentWindowAndBadSymbolGiveNothing) {
  const MArray a = *generate_marray(GenerationOptions{}).array;
  const WindowTable table(a, {3, 3});
  int absent = 0;
  for (std::uint64_t code = 0; code < 19683; ++code) absent += !table.find_code(code);
  EXPECT_EQ(absent, 19683 - 324);
  const std::uint8_t bad[9] = {0, 1, 2, 0, 7, 2, 0, 1, 2};
  EXPECT_FALSE(table.find(bad));
}

TEST(WindowTable, RejectsArraysWithoutTheWindowProperty) {
  const MArray a{4, 4, 2, std::vector<std::uint8_t>(16, 1)};
  EXPECT_THROW(WindowTable(a, {3, 3}), std::invalid_argument);
  EXPECT_THROW(WindowTable(a, {2, 2}), std::invalid_argument);
}

}  // namespace
}  // namespace pattern
