#include "servo/pattern/window_table.hpp"

#include <stdexcept>
#include <string>

namespace pattern {

WindowTable::WindowTable(const MArray& array, WindowShape window) : array_(array), window_(window) {
  if (window.rows % 2 == 0 || window.cols % 2 == 0)
    throw std::invalid_argument("WindowTable: window " + std::to_string(window.rows) + " x " +
                                std::to_string(window.cols) + " has no centre spot (sizes must be odd)");
  const WindowPropertyReport rep = check_window_property(array, window);
  if (!rep.holds) throw std::invalid_argument("WindowTable: the array does not have the window property");
  min_hamming_ = rep.min_hamming;
  const std::uint64_t space = code_space_size(array.colours, window);
  const bool dense = space <= (std::uint64_t{1} << 22);
  if (dense) dense_.assign(space, -1);
  for (int r = 0; r + window.rows <= array.rows; ++r)
    for (int c = 0; c + window.cols <= array.cols; ++c) {
      const std::uint64_t code = window_code(array, window, r, c);
      const std::int32_t centre = (r + window.rows / 2) * array.cols + (c + window.cols / 2);
      if (dense) dense_[code] = centre; else sparse_[code] = centre;
      ++count_;
    }
}

std::optional<SpotId> WindowTable::find_code(std::uint64_t code) const {
  std::int32_t idx = -1;
  if (!dense_.empty()) {
    if (code < dense_.size()) idx = dense_[code];
  } else if (auto it = sparse_.find(code); it != sparse_.end()) {
    idx = it->second;
  }
  if (idx < 0) return std::nullopt;
  return SpotId{idx / array_.cols, idx % array_.cols};
}

std::optional<SpotId> WindowTable::find(const std::uint8_t* colours) const {
  std::uint64_t code = 0;
  std::uint64_t pow = 1;
  for (int i = 0; i < window_.size(); ++i) {
    if (colours[i] >= array_.colours) return std::nullopt;
    code += colours[i] * pow;
    pow *= static_cast<std::uint64_t>(array_.colours);
  }
  return find_code(code);
}

}  // namespace pattern
