#include "servo/pattern/marray.hpp"

#include <array>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>
#include <unordered_set>

namespace pattern {
namespace {

std::uint64_t saturating_mul(std::uint64_t a, std::uint64_t b) {
  if (a != 0 && b > std::numeric_limits<std::uint64_t>::max() / a) return std::numeric_limits<std::uint64_t>::max();
  return a * b;
}

std::uint64_t binomial(int n, int r) {
  std::uint64_t c = 1;
  for (int i = 1; i <= r; ++i) c = c * static_cast<std::uint64_t>(n - r + i) / static_cast<std::uint64_t>(i);
  return c;
}

// Volume of a Hamming ball of the given radius in a code space of n symbols over k letters.
std::uint64_t hamming_ball(int n, int k, int radius) {
  std::uint64_t v = 0;
  std::uint64_t pow = 1;
  for (int i = 0; i <= radius; ++i) {
    v += saturating_mul(binomial(n, i), pow);
    pow = saturating_mul(pow, static_cast<std::uint64_t>(k - 1));
  }
  return v;
}

// The set of window codes already placed. Dense bitmap when the code space is small
// (3x3 windows over 3 colours: 19683 codes), a hash set otherwise.
class CodeSet {
 public:
  explicit CodeSet(std::uint64_t space) {
    if (space <= (std::uint64_t{1} << 26)) dense_.assign(space, false);
  }
  bool contains(std::uint64_t c) const { return dense_.empty() ? sparse_.count(c) != 0 : dense_[c]; }
  void insert(std::uint64_t c) {
    if (dense_.empty()) sparse_.insert(c); else dense_[c] = true;
  }
  void erase(std::uint64_t c) {
    if (dense_.empty()) sparse_.erase(c); else dense_[c] = false;
  }
  void clear() {
    if (dense_.empty()) sparse_.clear(); else std::fill(dense_.begin(), dense_.end(), false);
  }

 private:
  std::vector<bool> dense_;
  std::unordered_set<std::uint64_t> sparse_;
};

// True when some code within Hamming distance `radius` of `code` (itself included) is placed.
// Enumerates the ball: for 3x3 windows over 3 colours and radius 2 that is 163 codes.
bool ball_hits(const CodeSet& set, std::uint64_t code, int radius, int k, const std::vector<std::uint64_t>& pow,
               int first_digit) {
  if (set.contains(code)) return true;
  if (radius == 0) return false;
  const int n = static_cast<int>(pow.size());
  for (int i = first_digit; i < n; ++i) {
    const int digit = static_cast<int>((code / pow[i]) % k);
    for (int d = 0; d < k; ++d) {
      if (d == digit) continue;
      const std::uint64_t other = code - digit * pow[i] + d * pow[i];
      if (ball_hits(set, other, radius - 1, k, pow, i + 1)) return true;
    }
  }
  return false;
}

double cpu_seconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

}  // namespace

std::uint64_t code_space_size(int colours, WindowShape window) {
  std::uint64_t s = 1;
  for (int i = 0; i < window.size(); ++i) s = saturating_mul(s, static_cast<std::uint64_t>(colours));
  return s;
}

std::uint64_t window_code(const MArray& array, WindowShape window, int top, int left) {
  std::uint64_t code = 0;
  std::uint64_t pow = 1;
  for (int r = 0; r < window.rows; ++r)
    for (int c = 0; c < window.cols; ++c) {
      code += array.at(top + r, left + c) * pow;
      pow *= static_cast<std::uint64_t>(array.colours);
    }
  return code;
}

namespace {

// GF(3^6) as polynomials of degree < 6 over GF(3), modulo x^6 + x^5 + 2 (x^6 = 2 x^5 + 1),
// in which x is primitive (order 728).
using Gf729 = std::array<std::uint8_t, 6>;

Gf729 times_x(const Gf729& a) {
  Gf729 b{};
  for (int i = 5; i > 0; --i) b[i] = a[i - 1];
  b[0] = static_cast<std::uint8_t>(a[5] % 3);
  b[5] = static_cast<std::uint8_t>((b[5] + 2 * a[5]) % 3);
  return b;
}

Gf729 times(const Gf729& a, const Gf729& b) {
  Gf729 r{}, t = a;
  for (int i = 0; i < 6; ++i) {
    for (int k = 0; k < 6; ++k) r[k] = static_cast<std::uint8_t>((r[k] + b[i] * t[k]) % 3);
    t = times_x(t);
  }
  return r;
}

// Tr(a) = a + a^3 + a^9 + ... + a^243, an element of GF(3)
std::uint8_t trace(const Gf729& a) {
  Gf729 sum{}, t = a;
  for (int i = 0; i < 6; ++i) {
    for (int k = 0; k < 6; ++k) sum[k] = static_cast<std::uint8_t>((sum[k] + t[k]) % 3);
    t = times(times(t, t), t);
  }
  return sum[0];
}

}  // namespace

// A[r][c] = Tr(x^(offset + r + 107 c)) over GF(3^6): every 3 x 3 window is the image of
// one field element under a linear map of GF(3)^6 into GF(3)^9 whose code has minimum
// distance 3 ([9, 6, 3]), so windows of distinct elements are pairwise >= 3 apart. 107 is the
// column step that keeps the 324 elements of a 20 x 20 array's windows distinct.
MArray trace_marray(int rows, int cols, int offset) {
  std::vector<std::uint8_t> trace_of(728);
  Gf729 p{1, 0, 0, 0, 0, 0};
  for (int e = 0; e < 728; ++e) {
    trace_of[static_cast<std::size_t>(e)] = trace(p);
    p = times_x(p);
  }
  MArray a{rows, cols, 3, std::vector<std::uint8_t>(static_cast<std::size_t>(rows) * cols)};
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c)
      a.cells[static_cast<std::size_t>(r) * cols + c] = trace_of[static_cast<std::size_t>((offset + r + 107 * c) % 728)];
  return a;
}

namespace {

void check_generation_params(const GenerationOptions& p) {
  const auto fail_arg = [](const std::string& what) { throw std::invalid_argument("pattern generate: " + what); };
  if (p.colours < 2 || p.colours > 10) fail_arg("colours must be in 2..10, got " + std::to_string(p.colours));
  if (p.window.rows < 1 || p.window.cols < 1) fail_arg("window must be at least 1 x 1");
  if (p.rows < p.window.rows || p.cols < p.window.cols)
    fail_arg("array " + std::to_string(p.rows) + " x " + std::to_string(p.cols) + " is smaller than its window " +
             std::to_string(p.window.rows) + " x " + std::to_string(p.window.cols));
  if (p.min_hamming < 1 || p.min_hamming > p.window.size())
    fail_arg("min Hamming distance must be in 1.." + std::to_string(p.window.size()) + ", got " +
             std::to_string(p.min_hamming));
  if (!(p.time_budget_s > 0)) fail_arg("time budget must be positive");
}

// Why no array can exist (sphere packing), or "".
std::string packing_failure(const GenerationOptions& p, std::uint64_t space) {
  // Necessary condition (sphere packing): W windows, pairwise distance >= h, need
  // W * |ball of radius floor((h-1)/2)| <= k^(n m).
  const std::uint64_t windows =
      static_cast<std::uint64_t>(p.rows - p.window.rows + 1) * static_cast<std::uint64_t>(p.cols - p.window.cols + 1);
  const std::uint64_t ball = hamming_ball(p.window.size(), p.colours, (p.min_hamming - 1) / 2);
  if (saturating_mul(windows, ball) > space) {
    std::ostringstream s;
    s << "cannot be satisfied: " << windows << " windows at Hamming distance >= " << p.min_hamming << " need "
      << saturating_mul(windows, ball) << " codes but only " << space << " exist (k^" << p.window.size() << ")";
    return s.str();
  }
  return "";
}

// distance 3 over 3 colours in 3 x 3 windows: random search and annealing do not find it
// (issue 19), the algebraic construction does; the seed picks its starting power
GenerationResult trace_construction(const GenerationOptions& p) {
  GenerationResult result;
  const auto wall = std::chrono::steady_clock::now();
  MArray a = trace_marray(p.rows, p.cols, static_cast<int>((p.seed + 727) % 728));
  const WindowPropertyReport rep = check_window_property(a, p.window);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall).count();
  if (!rep.holds || rep.min_hamming < 3) {
    std::ostringstream s;
    s << "the GF(3^6) construction gives " << (rep.holds ? "windows at distance " + std::to_string(rep.min_hamming)
                                                         : std::string("repeated windows"))
      << " at " << p.rows << " x " << p.cols << "; it holds up to 20 x 20";
    result.failure = s.str();
    return result;
  }
  result.array = std::move(a);
  return result;
}

// Backtracking over the cells in raster order, each window's code kept at least min_hamming
// from every placed one, with restarts; within the time budget.
GenerationResult backtracking_search(const GenerationOptions& p, std::uint64_t space) {
  GenerationResult result;
  const double t0 = cpu_seconds();
  const auto wall0 = std::chrono::steady_clock::now();
  const auto elapsed = [&] { return cpu_seconds() - t0; };
  const int total = p.rows * p.cols;
  const int k = p.colours;
  std::vector<std::uint64_t> pow(p.window.size());
  pow[0] = 1;
  for (std::size_t i = 1; i < pow.size(); ++i) pow[i] = pow[i - 1] * static_cast<std::uint64_t>(k);

  MArray a{p.rows, p.cols, k, std::vector<std::uint8_t>(total, 0)};
  CodeSet placed(space);
  std::vector<std::uint64_t> placed_at(total, std::numeric_limits<std::uint64_t>::max());
  std::vector<std::uint8_t> tried(total, 0);
  std::vector<std::uint8_t> order(static_cast<std::size_t>(total) * k);
  std::mt19937_64 rng(p.seed);  // mt19937_64 is fully specified: same seed, same pattern, any platform

  const auto shuffle_colours = [&](int pos) {
    std::uint8_t* o = &order[static_cast<std::size_t>(pos) * k];
    for (int i = 0; i < k; ++i) o[i] = static_cast<std::uint8_t>(i);
    for (int i = k - 1; i > 0; --i) std::swap(o[i], o[rng() % static_cast<std::uint64_t>(i + 1)]);
  };
  const std::uint64_t restart_after = 64ull * static_cast<std::uint64_t>(total);
  std::uint64_t backtracks_since_restart = 0;

  int pos = 0;
  std::uint64_t steps = 0;
  while (pos < total) {
    if ((++steps & 0xfff) == 0 && elapsed() > p.time_budget_s) {
      std::ostringstream s;
      s << "no " << p.rows << " x " << p.cols << " array over " << k << " colours with unique "
        << p.window.rows << " x " << p.window.cols << " windows at Hamming distance >= " << p.min_hamming
        << " found within the time budget of " << p.time_budget_s << " s (" << result.restarts << " restarts)";
      result.failure = s.str();
      result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
      return result;
    }
    if (tried[pos] == 0) shuffle_colours(pos);
    const int r = pos / p.cols;
    const int c = pos % p.cols;
    const bool completes = r >= p.window.rows - 1 && c >= p.window.cols - 1;
    bool ok = false;
    while (tried[pos] < k) {
      a.cells[pos] = order[static_cast<std::size_t>(pos) * k + tried[pos]++];
      if (!completes) { ok = true; break; }
      const std::uint64_t code = window_code(a, p.window, r - p.window.rows + 1, c - p.window.cols + 1);
      if (ball_hits(placed, code, p.min_hamming - 1, k, pow, 0)) continue;
      placed.insert(code);
      placed_at[pos] = code;
      ok = true;
      break;
    }
    if (ok) { ++pos; continue; }

    // dead end: undo this cell, step back to the previous one and try its next colour
    tried[pos] = 0;
    ++result.backtracks;
    if (++backtracks_since_restart > restart_after || pos == 0) {
      ++result.restarts;
      backtracks_since_restart = 0;
      placed.clear();
      std::fill(placed_at.begin(), placed_at.end(), std::numeric_limits<std::uint64_t>::max());
      std::fill(tried.begin(), tried.end(), 0);
      pos = 0;
      continue;
    }
    --pos;
    if (placed_at[pos] != std::numeric_limits<std::uint64_t>::max()) {
      placed.erase(placed_at[pos]);
      placed_at[pos] = std::numeric_limits<std::uint64_t>::max();
    }
  }
  result.array = std::move(a);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return result;
}

}  // namespace

GenerationResult generate_marray(const GenerationOptions& p) {
  check_generation_params(p);
  const std::uint64_t space = code_space_size(p.colours, p.window);
  if (space == std::numeric_limits<std::uint64_t>::max())
    throw std::invalid_argument("pattern generate: window code space exceeds 64 bits");
  if (const std::string why = packing_failure(p, space); !why.empty()) {
    GenerationResult result;
    result.failure = why;
    return result;
  }
  if (p.min_hamming == 3 && p.colours == 3 && p.window.rows == 3 && p.window.cols == 3) return trace_construction(p);
  return backtracking_search(p, space);
}

namespace {

// Smallest Hamming distance between any two windows, all windows being distinct (d >= 1).
// Two windows are within distance d iff they agree once some d cells are masked out in
// both; so for d = 1, 2, ... every set of d masked cells is tried, the masked codes of all
// windows sorted and scanned for a repeat. Cost: W log W per mask, C(n, 1) + ... + C(n, d)
// masks for a distance of d (9 + 36 masks for the paper's 3 x 3 windows at d = 2), instead of
// the W^2 / 2 window pairs compared before (59 s for a 400 x 400 pattern).
// Also counts the window pairs at that distance: two windows at exactly the minimum distance
// d differ in exactly d cells, so they coincide under exactly one mask of d cells.
int min_hamming_distance(const MArray& array, WindowShape window, std::size_t count, std::uint64_t* pairs_at_min) {
  const int n = window.size();
  const std::uint64_t base = static_cast<std::uint64_t>(array.colours) + 1;  // digit value k: masked
  // codes must fit 64 bits and masks 32: beyond, only distinctness (d >= 1) is known, which is
  // all decoding needs
  if (n > 20 || code_space_size(static_cast<int>(base), window) == std::numeric_limits<std::uint64_t>::max()) {
    if (pairs_at_min) *pairs_at_min = 0;  // not counted
    return 1;
  }
  std::vector<std::uint8_t> digits;
  digits.reserve(count * static_cast<std::size_t>(n));
  for (int r = 0; r + window.rows <= array.rows; ++r)
    for (int c = 0; c + window.cols <= array.cols; ++c)
      for (int wr = 0; wr < window.rows; ++wr)
        for (int wc = 0; wc < window.cols; ++wc) digits.push_back(array.at(r + wr, c + wc));
  std::vector<std::uint64_t> codes(count);
  for (int d = 1; d < n; ++d) {
    std::uint64_t pairs = 0;
    // every mask of n bits with d set, in increasing order (Gosper's hack)
    for (std::uint32_t mask = (1u << d) - 1; mask < (1u << n);) {
      for (std::size_t w = 0; w < count; ++w) {
        std::uint64_t code = 0;
        const std::uint8_t* px = &digits[w * static_cast<std::size_t>(n)];
        for (int i = 0; i < n; ++i) code = code * base + ((mask >> i) & 1u ? array.colours : px[i]);
        codes[w] = code;
      }
      std::sort(codes.begin(), codes.end());
      for (std::size_t i = 0; i < codes.size();) {
        std::size_t j = i + 1;
        while (j < codes.size() && codes[j] == codes[i]) ++j;
        pairs += (j - i) * (j - i - 1) / 2;
        i = j;
      }
      if (pairs > 0 && !pairs_at_min) return d;
      const std::uint32_t lowest = mask & (~mask + 1u);
      const std::uint32_t ripple = mask + lowest;
      mask = (((ripple ^ mask) >> 2) / lowest) | ripple;
    }
    if (pairs > 0) {
      *pairs_at_min = pairs;
      return d;
    }
  }
  if (pairs_at_min) *pairs_at_min = count * (count - 1) / 2;  // all differ everywhere
  return n;
}

}  // namespace

WindowPropertyReport check_window_property(const MArray& array, WindowShape window) {
  WindowPropertyReport rep;
  if (array.rows < window.rows || array.cols < window.cols) return rep;
  struct W { std::uint64_t code; int top, left; };
  std::vector<W> ws;
  for (int r = 0; r + window.rows <= array.rows; ++r)
    for (int c = 0; c + window.cols <= array.cols; ++c) ws.push_back({window_code(array, window, r, c), r, c});
  rep.total_windows = static_cast<int>(ws.size());

  std::vector<W> sorted = ws;
  std::stable_sort(sorted.begin(), sorted.end(), [](const W& x, const W& y) { return x.code < y.code; });
  rep.distinct_windows = sorted.empty() ? 0 : 1;
  for (std::size_t i = 1; i < sorted.size(); ++i) {
    if (sorted[i].code != sorted[i - 1].code) {
      ++rep.distinct_windows;
    } else if (!rep.repeat) {
      rep.repeat = {{sorted[i - 1].top, sorted[i - 1].left}, {sorted[i].top, sorted[i].left}};
    }
  }
  rep.holds = rep.distinct_windows == rep.total_windows;

  rep.min_hamming = ws.size() < 2 || !rep.holds ? 0 : min_hamming_distance(array, window, ws.size(), &rep.pairs_at_min);
  return rep;
}

}  // namespace pattern
