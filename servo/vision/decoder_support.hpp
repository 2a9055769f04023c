// What the decoder's steps share (servo/vision/*.cpp, the stages of spot_decoder.hpp): the
// directions' id steps, a grid of the spots for neighbour queries, and the bookkeeping of the
// steps that name spots one at a time. Internal to servo_vision: nothing outside includes it.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "servo/pattern/marray.hpp"
#include "servo/vision/spot.hpp"
#include "servo/vision/spot_decoder.hpp"

namespace vision::decoder_support {


constexpr double kPi = 3.14159265358979323846;
// the id steps of the four directions, E S W N as (drow, dcol)
constexpr int kIdStep[4][2] = {{0, 1}, {1, 0}, {0, -1}, {-1, 0}};

// Buckets spots on a uniform grid so neighbour queries touch only nearby cells.
class SpatialGrid {
 public:
  SpatialGrid(const std::vector<Spot>& spots, double cell) : spots_(spots), cell_(cell) {
    double u0 = 1e18, v0 = 1e18, u1 = -1e18, v1 = -1e18;
    for (const Spot& s : spots) {
      u0 = std::min(u0, s.u), v0 = std::min(v0, s.v), u1 = std::max(u1, s.u), v1 = std::max(v1, s.v);
    }
    origin_u_ = u0, origin_v_ = v0;
    cols_ = std::max(1, static_cast<int>((u1 - u0) / cell) + 1);
    rows_ = std::max(1, static_cast<int>((v1 - v0) / cell) + 1);
    start_.assign(static_cast<std::size_t>(cols_) * rows_ + 1, 0);
    for (const Spot& s : spots) ++start_[key(s.u, s.v) + 1];
    for (std::size_t i = 1; i < start_.size(); ++i) start_[i] += start_[i - 1];
    index_.resize(spots.size());
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (std::size_t i = 0; i < spots.size(); ++i) index_[fill[key(spots[i].u, spots[i].v)]++] = static_cast<int>(i);
    u_.resize(spots.size()), v_.resize(spots.size());
    for (std::size_t k = 0; k < index_.size(); ++k) u_[k] = spots[index_[k]].u, v_[k] = spots[index_[k]].v;
  }
  // The spots of the cells within `reach` cells of (u, v), cell by cell in row-major order. The
  // cells of one row are consecutive keys, so their spots are one span of index_: a row costs
  // one span however many cells it has (an isolated blob's reach can span the whole image, which
  // cell by cell took a quarter of a ham frame's decoding), in the same order.
  template <typename F>
  void around(double u, double v, int reach, F&& f) const {
    const int cu = static_cast<int>((u - origin_u_) / cell_), cv = static_cast<int>((v - origin_v_) / cell_);
    const int c0 = std::max(0, cu - reach), c1 = std::min(cols_ - 1, cu + reach);
    if (c0 > c1) return;
    for (int r = std::max(0, cv - reach); r <= std::min(rows_ - 1, cv + reach); ++r) {
      const std::size_t row = static_cast<std::size_t>(r) * cols_;
      for (int i = start_[row + c0]; i < start_[row + c1 + 1]; ++i) f(index_[i]);
    }
  }
  // The spots of the cells that meet the disc of `radius` about (u, v), row by row as around()
  // meets them: each row's span trimmed to the disc's chord there. A link's reach is a disc of
  // 3.5 spacings, which a square of cells covers with twice its area: every spot of the disc,
  // in around()'s order, for half the visits. f(k0, k1): the grid's slots [k0, k1) (spot(k),
  // u(k), v(k): their positions lie side by side, a span is read without a branch per spot).
  template <typename F>
  void spans_in_disc(double u, double v, double radius, F&& f) const {
    const double gu = (u - origin_u_) / cell_, gv = (v - origin_v_) / cell_, gr = radius / cell_;
    const int r0 = std::max(0, static_cast<int>(std::floor(gv - gr)));
    const int r1 = std::min(rows_ - 1, static_cast<int>(std::floor(gv + gr)));
    for (int r = r0; r <= r1; ++r) {
      const double dv = std::max({0.0, r - gv, gv - (r + 1)});  // the row's nearest to the centre
      const double half = std::sqrt(std::max(0.0, gr * gr - dv * dv));
      const int c0 = std::max(0, static_cast<int>(std::floor(gu - half)));
      const int c1 = std::min(cols_ - 1, static_cast<int>(std::floor(gu + half)));
      const std::size_t row = static_cast<std::size_t>(r) * cols_;
      if (c0 <= c1) f(start_[row + c0], start_[row + c1 + 1]);
    }
  }
  template <typename F>
  void around_disc(double u, double v, double radius, F&& f) const {
    spans_in_disc(u, v, radius, [&](int k0, int k1) {
      for (int k = k0; k < k1; ++k) f(index_[k]);
    });
  }
  int spot(int k) const { return index_[k]; }
  double u(int k) const { return u_[k]; }
  double v(int k) const { return v_[k]; }

 private:
  std::size_t key(double u, double v) const {
    const int c = std::min(cols_ - 1, static_cast<int>((u - origin_u_) / cell_));
    const int r = std::min(rows_ - 1, static_cast<int>((v - origin_v_) / cell_));
    return static_cast<std::size_t>(r) * cols_ + c;
  }
  const std::vector<Spot>& spots_;
  double cell_;
  double origin_u_ = 0, origin_v_ = 0;
  int cols_ = 1, rows_ = 1;
  std::vector<int> start_, index_;
  std::vector<double> u_, v_;  // the spots' positions in index_'s order
};

inline double median(std::vector<double> x) {
  if (x.empty()) return 0;
  std::nth_element(x.begin(), x.begin() + x.size() / 2, x.end());
  return x[x.size() / 2];
}

// Three spots a, b, c in a row of the lattice on one smooth surface: the step b -> c close to
// a -> b. Across a depth edge the spot from the surface behind breaks it.
inline bool bends_little(const Spot& a, const Spot& b, const Spot& c, double bend) {
  const double su = c.u - 2 * b.u + a.u, sv = c.v - 2 * b.v + a.v;
  const double lu = c.u - b.u, lv = c.v - b.v, pu = b.u - a.u, pv = b.v - a.v;
  return su * su + sv * sv <= bend * bend * std::max(lu * lu + lv * lv, pu * pu + pv * pv);
}

// every row and column of the window (where all three spots are there) bends little, and each
// of its four lattice cells is near a parallelogram: a cell across a depth edge, with a spot
// from the surface behind shifted along its row, is not
inline bool smooth_window(const std::vector<Spot>& spots, const Window& w, const CellShape& shape) {
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) {
      const int a = w[3 * r + c], b = w[3 * r + c + 1], p = w[3 * r + c + 3], q = w[3 * r + c + 4];
      if (a < 0 || b < 0 || p < 0 || q < 0) continue;
      const double eu = spots[b].u - spots[a].u, ev = spots[b].v - spots[a].v;  // top side
      const double fu = spots[q].u - spots[p].u, fv = spots[q].v - spots[p].v;  // bottom side
      const double su = spots[p].u - spots[a].u, sv = spots[p].v - spots[a].v;  // left side
      const double du = eu - fu, dv = ev - fv;
      const double step2 = std::max(std::min(eu * eu + ev * ev, fu * fu + fv * fv), 0.0);
      const double side2 = su * su + sv * sv;
      // (the right side's difference from the left is the same vector)
      if (du * du + dv * dv > shape.cell_slack * shape.cell_slack * std::max(step2, 0.25 * side2)) return false;
    }
  for (int k = 0; k < 3; ++k) {
    const int r0 = w[3 * k], r1 = w[3 * k + 1], r2 = w[3 * k + 2];
    if (r0 >= 0 && r1 >= 0 && r2 >= 0 && !bends_little(spots[r0], spots[r1], spots[r2], shape.bend)) return false;
    const int c0 = w[k], c1 = w[k + 3], c2 = w[k + 6];
    if (c0 >= 0 && c1 >= 0 && c2 >= 0 && !bends_little(spots[c0], spots[c1], spots[c2], shape.bend)) return false;
  }
  return true;
}

// the colours of a window whose nine spots are all there, or nothing
inline std::optional<std::array<std::uint8_t, 9>> colours_of(const std::vector<Spot>& spots, const Window& w) {
  std::array<std::uint8_t, 9> c{};
  for (int i = 0; i < 9; ++i) {
    if (w[i] < 0) return std::nullopt;
    c[i] = static_cast<std::uint8_t>(spots[w[i]].colour);
  }
  return c;
}
// the window is whole, smooth and reads as a pattern window (on its epipolar lines when checked)
inline bool reads(const std::vector<Spot>& spots, const Window& w, const pattern::WindowTable& table,
           const EpipolarCheck* check, const CellShape& shape) {
  const auto c = colours_of(spots, w);
  if (!c) return false;
  const auto id = table.find(c->data());  // the code first: it is cheaper than the geometry
  return id && smooth_window(spots, w, shape) && (!check || check->confirms(w, *id));
}

// a blob smaller than `fraction` of the median area of the spots linked to it (DecoderOptions::fragment_area)
inline bool is_fragment(const std::vector<Spot>& spots, const AdjacencyGraph& graph, int i, double fraction) {
  std::array<int, 4> areas{};
  std::size_t m = 0;
  for (const int j : graph.next[i])
    if (j >= 0) areas[m++] = spots[j].area_px;
  if (m == 0) return false;
  for (std::size_t a = 1; a < m; ++a)  // insertion sort of at most four
    for (std::size_t b = a; b > 0 && areas[b - 1] > areas[b]; --b) std::swap(areas[b - 1], areas[b]);
  const double median = m % 2 ? areas[m / 2] : 0.5 * (areas[m / 2 - 1] + areas[m / 2]);
  return spots[i].area_px < fraction * median;
}


// the blob at least `fraction` of its source's strength and area (GrowthOptions::alike)
inline bool alike(const Spot& source, const Spot& s, double fraction) {
  return s.strength >= fraction * source.strength && s.area_px >= fraction * source.area_px;
}

// Which spot carries each id, and where each identified spot is in the decoded list: the
// bookkeeping of the steps that name spots one at a time (the grown lattice, the edge runs).
class IdMap {
 public:
  IdMap(const pattern::MArray& pattern, std::size_t spot_count, const std::vector<DecodedSpot>& decoded)
      : rows_(pattern.rows), cols_(pattern.cols), owner_(static_cast<std::size_t>(rows_) * cols_, -1),
        at_(spot_count, -1) {
    for (std::size_t i = 0; i < decoded.size(); ++i) add(decoded[i], static_cast<int>(i));
  }
  bool inside(int r, int c) const { return r >= 0 && c >= 0 && r < rows_ && c < cols_; }
  // the spot carrying id (r, c); -1 when none does or (r, c) is off the pattern
  int spot_at(int r, int c) const { return inside(r, c) ? owner_[static_cast<std::size_t>(r) * cols_ + c] : -1; }
  bool taken(int r, int c) const { return spot_at(r, c) >= 0; }
  // the spot's index in the decoded list, -1 while it has no id
  int index_of(int spot) const { return at_[spot]; }
  void add(const DecodedSpot& d, int index) {
    owner_[static_cast<std::size_t>(d.row) * cols_ + d.col] = d.spot;
    at_[d.spot] = index;
  }

 private:
  int rows_, cols_;
  std::vector<int> owner_;  // id -> spot
  std::vector<int> at_;     // spot -> index in decoded
};

// Each decoded spot whose blob is under `fraction` of the median area of the spots identified
// around its id (two or more of the 8): a speck (a far surface's wash, noise) or a spill's
// sliver that sits where the id's spot should be (DecoderOptions::speck_area).
inline std::vector<char> specks(const std::vector<Spot>& spots, const std::vector<DecodedSpot>& decoded,
                                const pattern::MArray& pattern, double fraction) {
  const IdMap ids(pattern, spots.size(), decoded);
  std::vector<char> out(decoded.size(), 0);
  for (std::size_t i = 0; i < decoded.size(); ++i) {
    std::array<int, 8> around{};  // at most 8, on the stack: a frame has hundreds
    int n = 0;
    for (int dr = -1; dr <= 1; ++dr)
      for (int dc = -1; dc <= 1; ++dc)
        if (const int j = ids.spot_at(decoded[i].row + dr, decoded[i].col + dc); (dr != 0 || dc != 0) && j >= 0)
          around[n++] = spots[j].area_px;
    if (n < 2) continue;
    std::nth_element(around.begin(), around.begin() + n / 2, around.begin() + n);  // the upper middle, as median()
    out[i] = spots[decoded[i].spot].area_px < fraction * around[n / 2];
  }
  return out;
}

// Spot j may take id X: the pattern has its colour at X, it lies on X's epipolar line, and no
// free id around X (`taken(row, col)` false) fits it as well: a step that skipped a missing
// spot or crossed a sheared column would otherwise pass an id on shifted by one.
template <typename Taken>
inline bool only_fitting_id(const std::vector<Spot>& spots, int j, const pattern::SpotId& x, const EpipolarCheck& check,
                     const pattern::MArray& pattern, Taken&& taken) {
  const auto fits = [&](int r, int c) { return pattern.at(r, c) == spots[j].colour && check.confirms(j, {r, c}); };
  if (pattern.at(x.row, x.col) != spots[j].colour || !check.confirms_grown(j, x)) return false;  // implies fits
  for (int dr = -1; dr <= 1; ++dr)
    for (int dc = -1; dc <= 1; ++dc) {
      const int r = x.row + dr, c = x.col + dc;
      if ((dr == 0 && dc == 0) || r < 0 || c < 0 || r >= pattern.rows || c >= pattern.cols || taken(r, c)) continue;
      if (fits(r, c)) return false;
    }
  return true;
}

// The pattern's ids of each colour, row-major (row * cols + col): a search for the lines of a
// spot's colour visits a third of the pattern.
inline std::vector<std::vector<int>> ids_by_colour(const pattern::MArray& pattern) {
  std::vector<std::vector<int>> out(static_cast<std::size_t>(std::max(0, pattern.colours)));
  for (int r = 0; r < pattern.rows; ++r)
    for (int c = 0; c < pattern.cols; ++c)
      if (const int k = pattern.at(r, c); k >= 0 && k < pattern.colours) out[k].push_back(r * pattern.cols + c);
  return out;
}

// Spot j, about to take id X from the lattice, lies nearer X's epipolar line than any other free
// id's of its colour, anywhere in the pattern (`taken(row, col)` false; `of_colour`: the
// pattern's ids of j's colour, ids_by_colour). The lattice's
// prediction and a spot of another surface can coincide: at a depth edge the surface behind
// shows a spot where the front lattice goes on, of the right colour, within the grown limit of
// X's line, and only its own id's line runs nearer. Over 1000 dark-ham poses (the tuning set)
// it kept 5 of the 9 wrong ids from step 6 for 0.8 % of the right ids (a rival line nearer by
// chance); the 4 it lets through lie nearer X's line than their own (a centroid pulled by an edge).
template <typename Taken>
bool nearest_free_line(int j, const pattern::SpotId& x, const EpipolarCheck& check, const pattern::MArray& pattern,
                       const std::vector<int>& of_colour, Taken&& taken) {
  const Eigen::Vector2d& xy = check.xy[static_cast<std::size_t>(j)];
  const double own = check.geometry.residual_px(xy, x);
  // a line fitted to the frame's spots (no calibration) is extrapolated beyond them, by pixels:
  // there a rival is heard within the tolerance (EpipolarGeometry::trusted)
  const double untrusted = check.geometry.tolerance_px();
  const double farthest = std::max(own, untrusted);
  for (const int k : of_colour) {
    // (the line's distance first: the ids beyond either bound, nearly all, cost a dot product)
    if (!(check.geometry.line_distance_px(xy, static_cast<std::size_t>(k)) <= farthest)) continue;
    const int r = k / pattern.cols, c = k % pattern.cols;
    if ((r != x.row || c != x.col) && !taken(r, c) &&
        check.geometry.residual_px(xy, {r, c}) <= (check.geometry.trusted({r, c}) ? own : untrusted))
      return false;
  }
  return true;
}

// Spot j, given id X by the lattice, is the only blob that could be X's spot on X's epipolar line
// (`rival(i)`: blob i could carry X), within the frame's grown limit: the converse of
// nearest_free_line, from the id's side. At a depth edge the front lattice goes on onto a spot of
// the surface behind whose own id's line coincides with X's there (the ham's lattice and the
// wall's (9, 19) on (6, 12)'s line, 0.05 px off it), so no line test tells them apart; X's own
// spot, past the silhouette, lies on that line elsewhere in the frame. A light ray lights one
// surface point: two blobs on X's line cannot both be X, and the lattice's prediction alone does
// not say which. Nor is it a margin: within the limit, noise decides which of the two lies
// nearer (the wall's real (6, 12) 0.09 px off, the blob the lattice named 0.05 px).
// (`of_colour`: the blobs of X's colour without an id: most of a frame's blobs are named, and a
// line crosses the whole image)
template <typename Rival>
bool nearest_free_blob(int j, const pattern::SpotId& x, const EpipolarCheck& check, const pattern::MArray& pattern,
                       const std::vector<int>& of_colour, Rival&& rival) {
  // a line fitted to the frame (no calibration) is extrapolated where it is not trusted
  if (!check.geometry.trusted(x)) return true;
  const double limit = std::min(check.grown_limit_px, check.geometry.tolerance_px());
  const auto line = static_cast<std::size_t>(x.row) * static_cast<std::size_t>(pattern.cols) + x.col;
  for (const int i : of_colour) {
    // (the line's distance first: nearly every blob lies far from it)
    if (i == j || !(check.geometry.line_distance_px(check.xy[static_cast<std::size_t>(i)], line) <= limit)) continue;
    if (check.confirms_grown(i, x) && rival(i)) return false;
  }
  return true;
}

// The spots on a grid whose cells are a lattice step wide (the median length of the graph's
// links); none without a link.
inline std::optional<SpatialGrid> lattice_grid(const std::vector<Spot>& spots, const AdjacencyGraph& graph) {
  // the squared lengths: their median's root is the lengths' median (median() takes an element)
  std::vector<double> squared;
  squared.reserve(2 * spots.size());
  for (std::size_t s = 0; s < spots.size(); ++s)
    for (const int k : {kEast, kSouth})
      if (const int j = graph.next[s][k]; j >= 0) {
        const double du = spots[j].u - spots[s].u, dv = spots[j].v - spots[s].v;
        squared.push_back(du * du + dv * dv);
      }
  if (squared.empty()) return std::nullopt;
  return SpatialGrid(spots, std::max(2.0, std::sqrt(median(std::move(squared)))));
}

// Links two identified spots whose ids are neighbours, where both ends had none that way.
template <class SpotAt>
void link_identified_neighbours(const std::vector<DecodedSpot>& decoded, SpotAt&& spot_at, AdjacencyGraph& graph) {
  for (const DecodedSpot& d : decoded)
    for (int k = 0; k < 4; ++k) {
      const int j = spot_at(d.row + kIdStep[k][0], d.col + kIdStep[k][1]);
      if (j >= 0 && graph.next[d.spot][k] < 0 && graph.next[j][(k + 2) % 4] < 0) {
        graph.next[d.spot][k] = j;
        graph.next[j][(k + 2) % 4] = d.spot;
      }
    }
}
}  // namespace vision::decoder_support
