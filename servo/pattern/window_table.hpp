// The look-up table of the paper's "spot decoding" step: every n x m window of the
// pattern, by its colour code, gives the (row, col) of the spot at its centre.
#pragma once

#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

#include "servo/pattern/marray.hpp"

namespace pattern {

struct SpotId {
  int row = 0;
  int col = 0;
  bool operator==(const SpotId&) const = default;
};

class WindowTable {
 public:
  // Throws std::invalid_argument if the array does not have the window property, or the
  // window has no centre (even sizes).
  WindowTable(const MArray& array, WindowShape window);

  // Centre spot of the window whose colours, read row-major, are `colours`.
  std::optional<SpotId> find(const std::uint8_t* colours) const;
  std::optional<SpotId> find_code(std::uint64_t code) const;

  const MArray& array() const { return array_; }
  WindowShape window() const { return window_; }
  std::size_t size() const { return count_; }
  int min_hamming() const { return min_hamming_; }

 private:
  MArray array_;
  WindowShape window_;
  std::size_t count_ = 0;
  int min_hamming_ = 0;
  // dense: code -> row * cols + col, -1 when absent (3^9 = 19683 entries for the paper's
  // pattern, one cache-friendly read per lookup); sparse when the code space is large
  std::vector<std::int32_t> dense_;
  std::unordered_map<std::uint64_t, std::int32_t> sparse_;
};

}  // namespace pattern
