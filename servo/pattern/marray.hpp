// M-arrays (perfect submaps) of coloured spots: the coded pattern of the paper's §3.
//
// A perfect submap is an r x v matrix over the alphabet {0..k-1} in which every n x m
// window appears at most once (the window property), so each window names its position.
// Generation follows Morano et al. (PAMI 1998): brute-force filling in raster order,
// each new cell drawn at random among the colours that keep every completed window unique
// (and, optionally, at Hamming distance >= h from every other window, Morano's robustness
// option), backtracking and restarting when a cell has no admissible colour.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace pattern {

// Row-major matrix of colour indices. Colour c of the paper's pattern: 0 blue, 1 green, 2 red.
struct MArray {
  int rows = 0;
  int cols = 0;
  int colours = 0;  // alphabet size k
  std::vector<std::uint8_t> cells;  // rows * cols, row-major

  std::uint8_t at(int row, int col) const { return cells[static_cast<std::size_t>(row) * cols + col]; }
  bool operator==(const MArray&) const = default;
};

struct WindowShape {
  int rows = 3;
  int cols = 3;
  int size() const { return rows * cols; }
};

struct GenerationOptions {
  int rows = 20;
  int cols = 20;
  int colours = 3;
  WindowShape window{3, 3};
  int min_hamming = 1;  // 1: windows only need to differ (the paper's pattern)
  std::uint64_t seed = 1;
  double time_budget_s = 30.0;  // give up (with a reason) after this much CPU time
};

struct GenerationResult {
  std::optional<MArray> array;  // empty when the request could not be met
  std::string failure;          // why, when array is empty
  double seconds = 0.0;
  std::uint64_t restarts = 0;
  std::uint64_t backtracks = 0;
};

// Throws std::invalid_argument for malformed parameters (sizes < window, k outside 2..10,
// h outside 1..window size). Requests that are well-formed but cannot be met (more windows
// than codes, Hamming bound exceeded, time budget exhausted) come back as a failure value.
GenerationResult generate_marray(const GenerationOptions& params);

// The algebraic distance-3 array over 3 colours (3 x 3 windows): A[r][c] = Tr(x^(offset + r +
// 107 c)) over GF(3^6) with modulus x^6 + x^5 + 2. At 20 x 20 its 324 windows are distinct and
// pairwise at Hamming distance >= 3 (issue 19); generate_marray checks it for other sizes.
MArray trace_marray(int rows, int cols, int offset);

// Window code: the window's colours read row-major, as base-k digits (least significant first).
std::uint64_t window_code(const MArray& array, WindowShape window, int top, int left);

struct WindowPropertyReport {
  bool holds = false;           // every window unique
  int total_windows = 0;
  int distinct_windows = 0;
  int min_hamming = 0;          // minimum Hamming distance between any two windows (0 if a repeat)
  std::uint64_t pairs_at_min = 0;  // window pairs at that distance (0 when not counted)
  // first repeated window found, as top-left corners of the two occurrences
  std::optional<std::pair<std::pair<int, int>, std::pair<int, int>>> repeat;
};

WindowPropertyReport check_window_property(const MArray& array, WindowShape window);

// Number of distinct window codes, k^(n*m), saturated at UINT64_MAX.
std::uint64_t code_space_size(int colours, WindowShape window);

}  // namespace pattern
