// M-array decoding, step 3: each complete neighbourhood read in the window table (read_windows, its votes),
// and 1 x N segments read along the epipolar lines with the calibration (read_segments).
#include <algorithm>
#include <cmath>
#include <optional>
#include <tuple>

#include "servo/vision/decoder_support.hpp"
#include "servo/vision/spot_decoder.hpp"

namespace vision {
using namespace decoder_support;

EpipolarCheck::EpipolarCheck(const EpipolarGeometry& g, const std::vector<Spot>& spots) : geometry(g) {
  xy.reserve(spots.size());
  for (const Spot& s : spots) xy.push_back(g.normalise(s.u, s.v));
}

void EpipolarCheck::set_grown_limit(const std::vector<DecodedSpot>& decoded, const GrownLimit& limit) {
  std::vector<double> residuals;
  residuals.reserve(decoded.size());
  for (const DecodedSpot& d : decoded) {
    const double r = geometry.residual_px(xy[static_cast<std::size_t>(d.spot)], {d.row, d.col});
    if (std::isfinite(r)) residuals.push_back(r);
  }
  grown_limit_px = grown_limit_of(std::move(residuals), limit, geometry.tolerance_px());
}

double grown_limit_of(std::vector<double> residuals, const GrownLimit& limit, double tolerance_px) {
  // too few (fewer than one window's spots) to say what the frame's residuals are: the tolerance alone
  if (residuals.size() < std::tuple_size_v<Window>) return tolerance_px;
  const auto mid = residuals.begin() + static_cast<std::ptrdiff_t>(residuals.size() / 2);
  std::nth_element(residuals.begin(), mid, residuals.end());
  return std::min(tolerance_px, std::max(limit.floor_px, limit.times_median * *mid));
}

bool EpipolarCheck::confirms(const Window& w, const pattern::SpotId& centre) const {
  for (int i = 0; i < 9; ++i)
    if (w[i] >= 0 && !confirms(w[i], {centre.row + i / 3 - 1, centre.col + i % 3 - 1})) return false;
  return true;
}




std::vector<WindowReading> read_windows(const std::vector<Spot>& spots, const Neighbourhoods& hoods,
                                        const pattern::WindowTable& table, const ToleranceOptions& tolerance,
                                        const EpipolarCheck* check, const CellShape& shape) {
  std::vector<WindowReading> out;
  const int k = table.array().colours;
  for (std::size_t s = 0; s < hoods.window.size(); ++s) {
    const Window& w = hoods.window[s];
    std::array<std::uint8_t, 9> colours{};
    int n_missing = 0;
    for (int i = 0; i < 9; ++i) {
      if (w[i] < 0) {
        ++n_missing;
        colours[i] = 0;
      } else {
        colours[i] = static_cast<std::uint8_t>(spots[w[i]].colour);
      }
    }
    // a window across a depth edge, however it reads, is not one lattice cell (tested after
    // the code, which is cheaper, rejects most windows)
    int smooth = -1;
    const auto is_smooth = [&] {
      if (smooth < 0) smooth = smooth_window(spots, w, shape);
      return smooth == 1;
    };
    if (n_missing == 0) {
      if (auto id = table.find(colours.data())) {
        if (!is_smooth()) continue;
        // a valid code on the wrong lines is a misread window: rejected, then maybe repaired
        if (!check || check->confirms(w, *id)) {
          out.push_back({static_cast<int>(s), *id, false});
          continue;
        }
      }
    }
    if (!tolerance.enabled || n_missing > tolerance.max_missing || !is_smooth()) continue;
    // error-tolerant: exactly one pattern window within one symbol of what was read (and, with
    // the epipolar check, on the epipolar lines)
    std::optional<pattern::SpotId> found;
    int matches = 0, found_wrong = -1;
    const auto try_window = [&](std::array<std::uint8_t, 9> c, int wrong) {
      if (auto id = table.find(c.data())) {
        if (check && !check->confirms(w, *id)) return;
        if (!found || !(*found == *id)) ++matches;
        found = id;
        found_wrong = wrong;
      }
    };
    if (n_missing > 0) {
      // every fill-in of the missing cells (k^n_missing of them): exactly one may fit
      std::array<int, 9> holes{};
      int h = 0;
      for (int i = 0; i < 9; ++i)
        if (w[i] < 0) holes[h++] = i;
      int combos = 1;
      for (int i = 0; i < h; ++i) combos *= k;
      for (int m = 0; m < combos; ++m) {
        auto cc = colours;
        for (int i = 0, v = m; i < h; ++i, v /= k) cc[holes[i]] = static_cast<std::uint8_t>(v % k);
        try_window(cc, -1);
      }
    } else {
      for (int i = 0; i < 9; ++i)
        for (int c = 0; c < k; ++c) {
          if (c == colours[i]) continue;
          auto cc = colours;
          cc[i] = static_cast<std::uint8_t>(c);
          try_window(cc, i);
        }
    }
    if (matches == 1) out.push_back({static_cast<int>(s), *found, true, found_wrong});
  }
  return out;
}

// Whether reading r votes for its window's cell i. A corrected window has one cell off the
// pattern window nearest it: that spot misread, or the row or column through it not the
// pattern's (the links skipped a row of dim spots, or crossed to a shifted one) and two of its
// three colours the next window's by chance. It votes for neither that cell nor the cells
// sharing its row or column, only for the four that share neither. The printed box read without
// the calibration (2000 poses) named row 15's spot row 14's 55 times, each backed by two
// corrected windows whose misread cell lay in that spot's row; without their votes 2 remain,
// its readable spots identified 43.7 % as before, the uncalibrated ham +0.3-0.5 points (fewer
// suspect votes contradict right ones) and nothing else changed in 72 tuning sweeps.
bool votes_for(const WindowReading& r, int i) {
  return r.wrong < 0 || (i / 3 != r.wrong / 3 && i % 3 != r.wrong % 3);
}

// A window's code places each of its lines only where the line's colours change along it: a
// row read within a run of one colour (the paper's pattern has runs of five) reads the same one
// step over. Across a depth edge the links can reach a row shifted by a step (the can's top,
// seen past its rim: the row there lies one column over from the side's lattice), and the window
// then reads exactly as its own and names that row's spots one column off: with the paper's
// pattern 12 of 12 wrong ids in 1000 can poses. A line is taken as shifted when it reads as the
// pattern one step along it and the spot linked beyond one of its ends shows the colour the
// shifted line has there, where that differs from the unshifted line's.
bool line_shifted(const LineContext& at, const Window& w, const pattern::SpotId& centre, int k) {
  const bool row = k < 3;
  const auto colour = [&](int t) {  // the pattern's colour t steps along the line from its middle
    const int r = row ? centre.row - 1 + k : centre.row + t, c = row ? centre.col + t : centre.col - 1 + (k - 3);
    return r >= 0 && c >= 0 && r < at.pattern.rows && c < at.pattern.cols ? int{at.pattern.at(r, c)} : -1;
  };
  // it reads the same one step along only when its three colours are one (a ninth of the lines)
  const int one = colour(0);
  if (colour(-1) != one || colour(1) != one) return false;
  const int first = row ? w[3 * k] : w[k - 3], last = row ? w[3 * k + 2] : w[k + 3];
  for (const int d : {-1, 1}) {
    if (colour(2 * d) != one) continue;  // one step along, the line would show another colour
    for (const int end : {-2, 2}) {
      const int spot = end < 0 ? first : last;
      const int beyond = spot >= 0 ? at.graph.next[spot][row ? (end < 0 ? 2 : 0) : (end < 0 ? 3 : 1)] : -1;
      if (beyond >= 0 && colour(end) != colour(end + d) && at.spots[beyond].colour == colour(end + d)) return true;
    }
  }
  return false;
}

void add_window_votes(const Neighbourhoods& hoods, const std::vector<WindowReading>& readings,
                      std::vector<IdVote>& votes, const LineContext* lines) {
  for (const WindowReading& r : readings) {
    const Window& w = hoods.window[r.centre];
    std::array<bool, 6> shifted{};
    if (lines) {
      // only a line of one colour can be shifted (line_shifted): the pattern's window, once
      const auto at = [&](int i) { return lines->pattern.at(r.id.row + i / 3 - 1, r.id.col + i % 3 - 1); };
      const std::array<std::uint8_t, 9> c{at(0), at(1), at(2), at(3), at(4), at(5), at(6), at(7), at(8)};
      for (int k = 0; k < 3; ++k) {
        if (c[3 * k] == c[3 * k + 1] && c[3 * k] == c[3 * k + 2]) shifted[k] = line_shifted(*lines, w, r.id, k);
        if (c[k] == c[k + 3] && c[k] == c[k + 6]) shifted[3 + k] = line_shifted(*lines, w, r.id, 3 + k);
      }
    }
    for (int i = 0; i < 9; ++i)
      if (w[i] >= 0 && votes_for(r, i) && !shifted[i / 3] && !shifted[3 + i % 3])
        votes.push_back({w[i], {r.id.row + i / 3 - 1, r.id.col + i % 3 - 1}, r.corrected});
  }
}



namespace {
// What step 3b asks of a run read as `ids`, beyond its colours and lines (read_segments).
struct RunContext {
  const std::vector<Spot>& spots;
  const AdjacencyGraph& graph;
  const EpipolarCheck& check;
  const std::vector<pattern::SpotId>& by_windows;  // per spot; row -1 where no window named it
  double alike;
};

// Each spot of the run alike the next along it: a spot of the surface behind an edge sits on
// the line the run goes on, but is fainter, or larger out of focus.
bool run_is_alike(const RunContext& at, const std::vector<int>& run) {
  for (std::size_t m = 1; m < run.size(); ++m) {
    const Spot &a = at.spots[run[m - 1]], &b = at.spots[run[m]];
    if (!alike(a, b, at.alike) || !alike(b, a, at.alike)) return false;
  }
  return true;
}

// Every spot of the run as close to its id's line as the frame's window-read spots lie to
// theirs (the grown limit, set from them).
bool run_is_tight(const RunContext& at, const std::vector<int>& run, const std::vector<pattern::SpotId>& ids) {
  for (std::size_t m = 0; m < run.size(); ++m)
    if (!at.check.confirms_grown(run[m], ids[m])) return false;
  return true;
}

// A spot of the run that a window named otherwise, or linked to a window-named spot whose id is
// not the step away its link says: at a silhouette a run can go on onto the surface behind,
// whose spot lies on the line of the id the run predicts and is linked to its own lattice.
bool run_meets_dissent(const RunContext& at, const std::vector<int>& run, const std::vector<pattern::SpotId>& ids) {
  for (std::size_t m = 0; m < run.size(); ++m) {
    const pattern::SpotId& own = at.by_windows[run[m]];
    if (own.row >= 0 && !(own == ids[m])) return true;
    for (int k = 0; k < 4; ++k) {
      const int j = at.graph.next[run[m]][k];
      if (j < 0 || at.by_windows[j].row < 0) continue;
      if (!(at.by_windows[j] == pattern::SpotId{ids[m].row + kIdStep[k][0], ids[m].col + kIdStep[k][1]})) return true;
    }
  }
  return false;
}
}  // namespace

void read_segments(const std::vector<Spot>& spots, const AdjacencyGraph& graph, const EpipolarCheck& check,
                   const pattern::MArray& pattern, int length, const std::vector<DecodedSpot>& by_windows,
                   std::vector<IdVote>& votes, const CellShape& shape, double alike_fraction) {
  // a run of 1 or 2 has no inner spot to vote for
  if (length < 3) return;
  // the ids each spot may carry: its colour, on its epipolar line (a handful of the 400)
  const std::vector<std::vector<int>> by_colour = ids_by_colour(pattern);
  std::vector<std::vector<pattern::SpotId>> candidates(spots.size());
  const auto candidates_of = [&](int i) -> const std::vector<pattern::SpotId>& {
    auto& out = candidates[i];
    if (out.empty() && spots[i].colour >= 0 && spots[i].colour < static_cast<int>(by_colour.size()))
      for (const int k : by_colour[spots[i].colour]) {
        // (the line's distance first: nearly every id's line passes far from the spot)
        if (check.geometry.line_distance_px(check.xy[i], static_cast<std::size_t>(k)) > check.geometry.tolerance_px())
          continue;
        const pattern::SpotId id{k / pattern.cols, k % pattern.cols};
        if (check.confirms(i, id)) out.push_back(id);
      }
    return out;
  };
  std::vector<pattern::SpotId> named(spots.size(), pattern::SpotId{-1, -1});
  for (const DecodedSpot& d : by_windows) named[d.spot] = {d.row, d.col};
  const RunContext at{spots, graph, check, named, alike_fraction};
  const int n = length;
  std::vector<int> run(static_cast<std::size_t>(n));
  std::vector<pattern::SpotId> ids(run.size());
  for (const auto& [forward, dr, dc] : {std::tuple{kEast, 0, 1}, std::tuple{kSouth, 1, 0}}) {
    for (std::size_t s = 0; s < spots.size(); ++s) {
      // the run from s, n - 1 links forward
      run[0] = static_cast<int>(s);
      bool whole = true;
      for (int m = 1; m < n && whole; ++m) whole = (run[m] = graph.next[run[m - 1]][forward]) >= 0;
      if (!whole) continue;
      // a run whose inner spots the windows all named adds nothing (a vote against them would
      // be a dissent): most of a frame's runs, read at no cost
      bool adds = false;
      for (int m = 1; m + 1 < n && !adds; ++m) adds = named[run[m]].row < 0;
      if (!adds) continue;
      // a run along one surface is smooth: each step close to the one before. At an object's
      // edge the run jumps to the surface behind, whose spot can sit on the same epipolar line
      bool smooth = true;
      for (int m = 1; m + 1 < n && smooth; ++m)
        smooth = bends_little(spots[run[m - 1]], spots[run[m]], spots[run[m + 1]], shape.bend);
      if (!smooth || !run_is_alike(at, run)) continue;
      // exactly one place in the pattern has the run's colours along the axis, each spot within
      // the tolerance of its id's line: a run that fits two places is dropped
      int matches = 0;
      pattern::SpotId found{};
      for (const pattern::SpotId& a : candidates_of(static_cast<int>(s))) {
        bool fits = true;
        for (int m = 1; m < n && fits; ++m) {
          const pattern::SpotId id{a.row + m * dr, a.col + m * dc};
          fits = id.row < pattern.rows && id.col < pattern.cols && pattern.at(id.row, id.col) == spots[run[m]].colour &&
                 check.confirms(run[m], id);
        }
        if (fits && ++matches == 1) found = a;
        if (matches > 1) break;
      }
      if (matches != 1) continue;
      for (int m = 0; m < n; ++m) ids[m] = {found.row + m * dr, found.col + m * dc};
      if (!run_is_tight(at, run, ids) || run_meets_dissent(at, run, ids)) continue;
      // the run votes for its spots but its two ends: where a run crosses an edge, its last spot
      // is the surface behind's, and a spot inside it has runs that go on past it
      for (int m = 1; m + 1 < n; ++m) votes.push_back({run[m], ids[m]});
    }
  }
}

}  // namespace vision
