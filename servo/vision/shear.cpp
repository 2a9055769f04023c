// M-array decoding, step 2b: a lattice sheared by one column (or row) between two lines, resolved by the
// windows each choice reads (resolve_shear).
#include <algorithm>
#include <cmath>
#include <optional>
#include <tuple>

#include "servo/vision/decoder_support.hpp"
#include "servo/vision/spot_decoder.hpp"

namespace vision {
using namespace decoder_support;

namespace {

// The line through t, m, b (before, the spot, after) goes straight on: a shear slants it,
// curvature bends it a little; its two steps are alike in length.
bool goes_straight(const Spot& t, const Spot& m, const Spot& b, const CellShape& shape) {
  const double eu = t.u + b.u - 2 * m.u, ev = t.v + b.v - 2 * m.v;
  const double lt = (t.u - m.u) * (t.u - m.u) + (t.v - m.v) * (t.v - m.v);
  const double lb = (b.u - m.u) * (b.u - m.u) + (b.v - m.v) * (b.v - m.v);
  const double bend2 = shape.bend * shape.bend, ratio2 = shape.step_ratio * shape.step_ratio;
  return eu * eu + ev * ev <= bend2 * std::max(lt, lb) && lt <= ratio2 * lb && lb <= ratio2 * lt;
}

// Rewrites the links across of every spot whose choice (before, after) a neighbour along the
// line backs, and keeps the graph symmetric.
AdjacencyGraph apply_shear_choices(const AdjacencyGraph& graph, const std::vector<std::array<int, 2>>& proposal,
                                   std::vector<char> proposed, Direction along, Direction across) {
  const auto back = static_cast<Direction>((along + 2) % 4), reverse = static_cast<Direction>((across + 2) % 4);
  const std::size_t n = graph.next.size();
  const auto step = [&](int i, Direction d) { return i < 0 ? -1 : graph.next[i][d]; };
  AdjacencyGraph out = graph;
  // A shear slants a region, not one spot: a choice is taken when a neighbour along the line
  // has links across (its own choice, or the links it has) that are the same choice moved
  // along. A window that reads by chance after a shift (1 in 60 codes is valid) stands alone.
  const auto links_of = [&](int x) {
    return proposed[x] ? proposal[x] : std::array<int, 2>{step(x, reverse), step(x, across)};
  };
  std::vector<char> taken(n, 0);
  for (std::size_t s = 0; s < n; ++s) {
    if (!proposed[s]) continue;
    const auto [t, u] = proposal[s];
    for (const Direction d : {back, along}) {
      const int x = graph.next[s][d];
      if (x < 0) continue;
      const auto [xt, xu] = links_of(x);
      if (xt >= 0 && xu >= 0 && xt == step(t, d) && xu == step(u, d)) taken[s] = 1;
    }
  }
  for (std::size_t s = 0; s < n; ++s) proposed[s] = taken[s];
  for (std::size_t s = 0; s < n; ++s) {
    if (!proposed[s]) continue;
    const auto [t, u] = proposal[s];
    out.next[s][reverse] = t;
    out.next[s][across] = u;
    // the other end takes the link back unless it has a choice of its own
    if (!proposed[t]) out.next[t][across] = static_cast<int>(s);
    if (!proposed[u]) out.next[u][reverse] = static_cast<int>(s);
  }
  // keep the graph symmetric: a link across that lost its other end is dropped
  for (std::size_t s = 0; s < n; ++s)
    for (const Direction k : {reverse, across}) {
      const int j = out.next[s][k];
      if (j >= 0 && out.next[j][(k + 2) % 4] != static_cast<int>(s)) out.next[s][k] = -1;
    }
  return out;
}

}  // namespace

AdjacencyGraph resolve_shear(const std::vector<Spot>& spots, const AdjacencyGraph& graph, const Neighbourhoods& hoods,
                             const pattern::WindowTable& table, const EpipolarCheck* check, ShearAxis axis,
                             const CellShape& shape) {
  // `along`: the direction of the lines trusted (rows when columns are resolved); `across`: the
  // links rewritten, from the line before (reverse) to the line after (across)
  const bool columns = axis == ShearAxis::kColumns;
  const Direction along = columns ? kEast : kSouth, back = columns ? kWest : kNorth;
  const Direction across = columns ? kSouth : kEast, reverse = columns ? kNorth : kWest;
  // the window cell of position a across (0 before, 1 the spot's line, 2 after) and b along
  const auto cell = [&](int a, int b) { return columns ? 3 * a + b : 3 * b + a; };
  const std::size_t n = spots.size();
  const auto step = [&](int i, Direction d) { return i < 0 ? -1 : graph.next[i][d]; };
  // a line's three spots centred on c (or nothing when c lacks a link along it)
  const auto line_of = [&](int c) -> std::optional<std::array<int, 3>> {
    if (c < 0 || graph.next[c][back] < 0 || graph.next[c][along] < 0) return std::nullopt;
    return std::array<int, 3>{graph.next[c][back], c, graph.next[c][along]};
  };
  // the spots that may centre the line before (after) i: its linked one, and the ones reached
  // through its neighbours along the line, each shifted by -1, 0, +1 along theirs
  const auto centres = [&](int i, Direction d, std::array<int, 9>& found) {
    int m = 0;
    for (const int x : {step(i, d), step(step(step(i, back), d), along), step(step(step(i, along), d), back)})
      for (const int y : {x, step(x, back), step(x, along)})
        if (y >= 0 && y != i && std::find(found.begin(), found.begin() + m, y) == found.begin() + m) found[m++] = y;
    return m;
  };
  std::vector<std::array<int, 2>> proposal(n, {-1, -1});  // before, after
  std::vector<char> proposed(n, 0);
  std::array<int, 9> befores{}, afters{};
  for (std::size_t s = 0; s < n; ++s) {
    const int i = static_cast<int>(s);
    if (reads(spots, hoods.window[s], table, check, shape)) continue;  // its links read already
    const auto middle = line_of(i);
    if (!middle) continue;
    const int nt = centres(i, reverse, befores), nb = centres(i, across, afters);
    int matches = 0;
    std::array<int, 2> best{-1, -1};
    for (int a = 0; a < nt && matches <= 1; ++a)
      for (int b = 0; b < nb && matches <= 1; ++b) {
        const int t = befores[a], u = afters[b];
        if (t == u) continue;
        if (!goes_straight(spots[t], spots[i], spots[u], shape)) continue;
        const auto first = line_of(t), last = line_of(u);
        if (!first || !last) continue;
        Window w{};
        for (int k = 0; k < 3; ++k) {
          w[cell(0, k)] = (*first)[k];
          w[cell(1, k)] = (*middle)[k];
          w[cell(2, k)] = (*last)[k];
        }
        if (!reads(spots, w, table, check, shape)) continue;
        ++matches;
        best = {t, u};
      }
    if (matches != 1 || (best[0] == graph.next[s][reverse] && best[1] == graph.next[s][across])) continue;
    proposal[s] = best;
    proposed[s] = 1;
  }
  return apply_shear_choices(graph, proposal, proposed, along, across);
}

}  // namespace vision
