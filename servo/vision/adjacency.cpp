// M-array decoding, steps 1 and 2: the four-neighbour graph of the spots (build_adjacency, mended), and
// the 3 x 3 neighbourhoods whose corners agree (check_graph_consistency).
#include <algorithm>
#include <cmath>
#include <optional>
#include <tuple>

#include "servo/vision/decoder_support.hpp"
#include "servo/vision/spot_decoder.hpp"

namespace vision {
using namespace decoder_support;

namespace {

// Rows are linked far more reliably than columns (the spacing along a row is regular; down a
// column, shear and foreshortening make a diagonal neighbour compete with the true one). Two
// rows of the pattern that lie one above the other are joined by one column offset: the links
// between two row chains vote for it, and when most agree, every spot of the two chains is
// linked by it (a link the nearest-spot rule got wrong or missed is mended). Which offset is
// the pattern's own, not a shear of it, the code decides later (resolve_column_shear).
void align_chains(AdjacencyGraph& g, Direction along, Direction across, const AdjacencyOptions& o) {
  const auto back = static_cast<Direction>((along + 2) % 4), reverse = static_cast<Direction>((across + 2) % 4);
  const std::size_t n = g.next.size();
  std::vector<int> chain(n, -1), pos(n, 0);
  std::vector<std::vector<int>> chains;
  for (std::size_t s = 0; s < n; ++s) {
    if (chain[s] >= 0) continue;
    int head = static_cast<int>(s);
    // walk west to the chain's start (bounded: the links are mutual, a chain cannot loop back)
    for (std::size_t guard = 0; g.next[head][back] >= 0 && guard < n; ++guard) head = g.next[head][back];
    if (chain[head] >= 0) continue;
    const int id = static_cast<int>(chains.size());
    chains.emplace_back();
    for (int x = head; x >= 0 && chain[x] < 0; x = g.next[x][along]) {
      chain[x] = id;
      pos[x] = static_cast<int>(chains.back().size());
      chains.back().push_back(x);
    }
  }
  // votes: (upper chain, lower chain, offset) from every south link
  struct Vote {
    int upper, lower, offset;
    bool operator<(const Vote& o) const { return std::tie(upper, lower, offset) < std::tie(o.upper, o.lower, o.offset); }
  };
  std::vector<Vote> votes;
  for (std::size_t s = 0; s < n; ++s) {
    const int j = g.next[s][across];
    if (j >= 0 && chain[j] >= 0 && chain[j] != chain[s]) votes.push_back({chain[s], chain[j], pos[j] - pos[static_cast<int>(s)]});
  }
  std::sort(votes.begin(), votes.end());
  // per chain pair: the offset most links take, when at least o.chain_votes and o.chain_share of them do
  struct Join {
    int upper, lower, offset;
  };
  std::vector<Join> joins;
  for (std::size_t a = 0; a < votes.size();) {
    std::size_t b = a;
    int total = 0, best = 0, best_offset = 0;
    while (b < votes.size() && votes[b].upper == votes[a].upper && votes[b].lower == votes[a].lower) {
      std::size_t c = b;
      while (c < votes.size() && votes[c].upper == votes[b].upper && votes[c].lower == votes[b].lower &&
             votes[c].offset == votes[b].offset)
        ++c;
      const int count = static_cast<int>(c - b);
      total += count;
      if (count > best) best = count, best_offset = votes[b].offset;
      b = c;
    }
    if (best >= o.chain_votes && best >= o.chain_share * total) joins.push_back({votes[a].upper, votes[a].lower, best_offset});
    a = b;
  }
  // a spot joined to two lower chains (or two upper) keeps its links as they are
  std::vector<int> south(n, -1), claims(n, 0), north_claims(n, 0);
  for (const Join& j : joins) {
    const auto& up = chains[j.upper];
    const auto& low = chains[j.lower];
    for (int k = 0; k < static_cast<int>(up.size()); ++k) {
      const int m = k + j.offset;
      if (m < 0 || m >= static_cast<int>(low.size())) continue;
      south[up[k]] = low[m];
      ++claims[up[k]];
      ++north_claims[low[m]];
    }
  }
  for (std::size_t s = 0; s < n; ++s) {
    const int j = south[s];
    if (j < 0 || claims[s] != 1 || north_claims[j] != 1 || g.next[s][across] == j) continue;
    // unlink what each end had, then link them
    if (g.next[s][across] >= 0) g.next[g.next[s][across]][reverse] = -1;
    if (g.next[j][reverse] >= 0) g.next[g.next[j][reverse]][across] = -1;
    g.next[s][across] = j;
    g.next[j][reverse] = static_cast<int>(s);
  }
}

// Completion from the lattice around: a link the nearest-candidate rule missed (a column whose
// candidates two spots contend for, a row squeezed towards the silhouette past the spacing
// rule) is where the neighbours' links say it is. The spot missing its south link takes the
// step its east and west neighbours take south, and links the spot found there if that one
// has no north link yet. Two rounds: a completed link lends its step to the next.
void complete_links(AdjacencyGraph& g, const std::vector<Spot>& spots, const SpatialGrid& near, double slack) {
  const std::size_t n = spots.size();
  for (int round = 0; round < 2; ++round) {
    std::vector<std::array<int, 4>> add(n, {-1, -1, -1, -1});
    for (std::size_t s = 0; s < n; ++s)
      for (int k = 0; k < 4; ++k) {
        if (g.next[s][k] >= 0) continue;
        // the two directions across k: their spots' steps in k
        double vu = 0, vv = 0;
        int refs = 0;
        for (const int across : {(k + 1) % 4, (k + 3) % 4}) {
          const int x = g.next[s][across];
          if (x < 0 || g.next[x][k] < 0) continue;
          vu += spots[g.next[x][k]].u - spots[x].u;
          vv += spots[g.next[x][k]].v - spots[x].v;
          ++refs;
        }
        if (refs == 0) continue;
        vu /= refs, vv /= refs;
        const double pu = spots[s].u + vu, pv = spots[s].v + vv, step2 = vu * vu + vv * vv;
        int found = -1;
        double best = slack * slack * step2;
        near.around(pu, pv, 1, [&](int j) {
          const double du = spots[j].u - pu, dv = spots[j].v - pv;
          if (j != static_cast<int>(s) && du * du + dv * dv <= best) best = du * du + dv * dv, found = j;
        });
        if (found >= 0 && g.next[found][(k + 2) % 4] < 0) add[s][k] = found;
      }
    bool grew = false;
    for (std::size_t s = 0; s < n; ++s)
      for (int k = 0; k < 4; ++k) {
        const int j = add[s][k];
        // both ends must agree: j found s, or j had nothing to say in that direction
        if (j < 0 || g.next[s][k] >= 0 || g.next[j][(k + 2) % 4] >= 0) continue;
        const int back = add[j][(k + 2) % 4];
        if (back >= 0 && back != static_cast<int>(s)) continue;
        g.next[s][k] = j;
        g.next[j][(k + 2) % 4] = static_cast<int>(s);
        grew = true;
      }
    if (!grew) break;
  }
}

// Each spot's nearest neighbour distance, and the grid's direction (modulo 90 deg, the mean of
// the nearest-neighbour directions x 4) into `grid_angle_rad`; a first spacing estimate from
// a coarse grid finds the neighbours.
std::vector<double> nearest_distances(const std::vector<Spot>& spots, double& grid_angle_rad) {
  const std::size_t n = spots.size();
  double u0 = 1e18, v0 = 1e18, u1 = -1e18, v1 = -1e18;
  for (const Spot& s : spots) u0 = std::min(u0, s.u), v0 = std::min(v0, s.v), u1 = std::max(u1, s.u), v1 = std::max(v1, s.v);
  const double coarse = std::max(4.0, std::sqrt(std::max(1.0, (u1 - u0) * (v1 - v0)) / static_cast<double>(n)));
  const SpatialGrid grid(spots, coarse);
  std::vector<double> nn_dist(n, 0);
  double sx = 0, sy = 0;  // angle x 4 sums: the grid direction modulo 90 deg
  for (std::size_t i = 0; i < n; ++i) {
    double best = 1e18;
    int bj = -1;
    const auto nearer = [&](int j) {
      if (j == static_cast<int>(i)) return;
      const double du = spots[j].u - spots[i].u, dv = spots[j].v - spots[i].v;
      const double d2 = du * du + dv * dv;  // squared: std::hypot is ten times dearer and not needed
      if (d2 < best) best = d2, bj = j;
    };
    // The nearest within two cells. The adjacent cells first: when what they hold lies within
    // two cells, the disc through it lies inside the two cells' square, and its cells, met in
    // the square's order, hold the square's first nearest (the same spot, ties and all).
    grid.around(spots[i].u, spots[i].v, 1, nearer);
    if (best <= 4 * coarse * coarse) {
      const double radius = std::sqrt(best);
      best = 1e18, bj = -1;
      grid.around_disc(spots[i].u, spots[i].v, radius, nearer);
    } else {
      best = 1e18, bj = -1;
      grid.around(spots[i].u, spots[i].v, 2, nearer);
    }
    if (bj < 0) continue;
    nn_dist[i] = std::sqrt(best);
    // (cos 4a, sin 4a) as the fourth power of the unit vector (x + iy): no trigonometry
    const double x = (spots[bj].u - spots[i].u) / nn_dist[i], y = (spots[bj].v - spots[i].v) / nn_dist[i];
    const double c2 = x * x - y * y, s2 = 2 * x * y;
    sx += c2 * c2 - s2 * s2;
    sy += 2 * c2 * s2;
  }
  grid_angle_rad = std::atan2(sy, sx) / 4.0;
  return nn_dist;
}

// One spot's candidate neighbours: rows first (the closest spot within +-35 deg,
// o.row_cone_deg, of the pattern's east and west), then columns against the spot's own row
// direction. Under perspective the columns shear away from the perpendicular and a diagonal
// neighbour can be nearer than the true one, so the north and south candidates are ranked by
// distance weighted by their angle to the local perpendicular.
class CandidateSearch {
 public:
  CandidateSearch(const std::vector<Spot>& spots, const SpatialGrid& near, double grid_angle_rad, const AdjacencyOptions& o)
      : spots_(spots), near_(near), o_(o), ce_(std::cos(grid_angle_rad)), se_(std::sin(grid_angle_rad)), around_(spots.size()) {
    const double row_cos = std::cos(o.row_cone_deg * kPi / 180.0), col_cos = std::cos(o.column_cone_deg * kPi / 180.0);
    row_cos2_ = row_cos * row_cos, col_cos2_ = col_cos * col_cos;
  }

  // Within `reach` of spot i. The true neighbours lie about a spacing away, the reach is 3.5
  // spacings (a link may bridge a missing spot): the disc of 2 is searched first, and what
  // it finds is final when nothing beyond could do better (a row's nearest; a column's score,
  // at least its distance, under the small disc's radius). Beyond it, the whole reach, in the
  // same order: the same candidates, ties and all, for a third of the visits; for the columns,
  // when both were found, only as far as the worse of their scores (on the ham's frames half
  // the spots searched again for a column, 12 % fewer spots visited in all).
  std::array<int, 4> operator()(int i, double reach, double near_reach) {
    std::array<int, 4> cand{-1, -1, -1, -1};
    const bool two = near_reach < reach;
    gather(i, two ? near_reach : reach);
    rows(cand);
    bool whole = !two;
    if (two && (cand[kEast] < 0 || cand[kWest] < 0)) gather(i, reach), rows(cand), whole = true;
    const std::array<double, 2> score = columns(i, cand);
    if (whole) return cand;
    // none beyond the worse of both columns' scores can win: the disc that far holds the whole
    // reach's winners, ties and all (it lists its spots in the whole reach's order)
    const bool both = cand[kSouth] >= 0 && cand[kNorth] >= 0;
    const double enough = both ? std::min(reach, std::max(score[0], score[1])) : reach;
    if (enough > near_reach) gather(i, enough), columns(i, cand);
    return cand;
  }

 private:
  struct Candidate {
    int j;
    double du, dv, d2;  // squared distance: the square root only for the few in a cone
  };
  // (every slot is written and the count advances only for a spot in reach: a branch on the
  // distance mispredicted on half the visits)
  void gather(int i, double reach) {
    const double reach2 = reach * reach, u = spots_[i].u, v = spots_[i].v;
    std::size_t n = 0;
    near_.spans_in_disc(u, v, reach, [&](int k0, int k1) {
      for (int k = k0; k < k1; ++k) {
        const double du = near_.u(k) - u, dv = near_.v(k) - v, d2 = du * du + dv * dv;
        around_[n] = {near_.spot(k), du, dv, d2};
        n += (d2 <= reach2) & (d2 > 1e-18);  // (j == i has d2 = 0)
      }
    });
    in_reach_ = n;
  }
  // rows: cos >= row_cos, i.e. dot >= 0 and dot^2 >= row_cos^2 d^2
  void rows(std::array<int, 4>& cand) const {
    std::array<double, 2> best{1e300, 1e300};
    cand[kEast] = cand[kWest] = -1;
    for (const Candidate& c : in_reach()) {
      const double dot = c.du * ce_ + c.dv * se_;
      if (dot * dot < row_cos2_ * c.d2) continue;
      const int side = dot > 0 ? 0 : 1;
      if (c.d2 < best[side]) best[side] = c.d2, cand[side == 0 ? kEast : kWest] = c.j;
    }
  }
  // columns, against this spot's row direction (from its east and west candidates when it has
  // them); the best south and north scores
  std::array<double, 2> columns(int i, std::array<int, 4>& cand) const {
    double ru = ce_, rv = se_;
    const int e = cand[kEast], w = cand[kWest];
    if (e >= 0 || w >= 0) {
      ru = rv = 0;
      for (const auto& [j, sign] : {std::pair{e, 1.0}, std::pair{w, -1.0}}) {
        if (j < 0) continue;
        const double du = spots_[j].u - spots_[i].u, dv = spots_[j].v - spots_[i].v, d = std::sqrt(du * du + dv * dv);
        ru += sign * du / d;
        rv += sign * dv / d;
      }
      const double norm = std::sqrt(ru * ru + rv * rv);
      ru /= norm, rv /= norm;
    }
    const double pu = -rv, pv = ru;  // the perpendicular, pointing south (image y down)
    std::array<double, 2> best{1e300, 1e300};
    cand[kSouth] = cand[kNorth] = -1;
    for (const Candidate& c : in_reach()) {
      const double dot = c.du * pu + c.dv * pv;
      if (dot * dot < col_cos2_ * c.d2) continue;
      // a score is at least its distance: one as far as its side's best cannot win (the
      // square root of best * best is best exactly, so this skips only what would lose)
      const double side_best = dot > 0 ? best[0] : best[1];
      if (c.d2 >= side_best * side_best) continue;
      const double d = std::sqrt(c.d2);
      const double cosine = std::min(1.0, std::abs(dot) / d);
      // ~ d (1 + 2 angle): sqrt(2 (1 - cos)) is the angle to within 4 % below 45 deg, sans acos
      const double score = d * (1.0 + o_.angle_weight * std::sqrt(2.0 * (1.0 - cosine)));
      if (dot > 0 && score < best[0]) best[0] = score, cand[kSouth] = c.j;
      if (dot < 0 && score < best[1]) best[1] = score, cand[kNorth] = c.j;
    }
    return best;
  }

  const std::vector<Spot>& spots_;
  const SpatialGrid& near_;
  const AdjacencyOptions& o_;
  double ce_, se_, row_cos2_ = 0, col_cos2_ = 0;
  // one spot's neighbours within reach: the first in_reach_ (room for every spot, made once)
  std::vector<Candidate> around_;
  std::size_t in_reach_ = 0;
  struct Span {
    const Candidate *b, *e;
    const Candidate* begin() const { return b; }
    const Candidate* end() const { return e; }
  };
  Span in_reach() const { return {around_.data(), around_.data() + in_reach_}; }
};

// The candidate east, south, west and north neighbours of every spot.
std::vector<std::array<int, 4>> link_candidates(const std::vector<Spot>& spots, const SpatialGrid& near,
                                                const std::vector<double>& nn_dist, double spacing,
                                                double grid_angle_rad, const AdjacencyOptions& o) {
  std::vector<std::array<int, 4>> cand(spots.size());
  CandidateSearch search(spots, near, grid_angle_rad, o);
  for (std::size_t i = 0; i < spots.size(); ++i) {
    const double unit = std::max(nn_dist[i], 0.5 * spacing);
    cand[i] = search(static_cast<int>(i), o.reach * unit, 2.0 * unit);
  }
  return cand;
}

// The links kept: mutual candidates, regularly spaced, symmetric.
void keep_regular_links(const std::vector<Spot>& spots, const std::vector<std::array<int, 4>>& cand,
                        double step_ratio, AdjacencyGraph& g) {
  const std::size_t n = spots.size();
  std::vector<std::array<int, 4>> mutual(n, {-1, -1, -1, -1});
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 4; ++k) {
      const int j = cand[i][k];
      if (j >= 0 && cand[j][(k + 2) % 4] == static_cast<int>(i)) mutual[i][k] = j;
    }
  // Regular spacing: a link across a missing spot is twice as long as the links continuing it
  // on either side. Spacing varies smoothly along a row or column (perspective, curvature), so
  // a link is kept when a continuing link has a similar length, or when none exists to compare.
  const auto length = [&](int a, int b) {  // (std::hypot guards an overflow no pixel offset comes near, at 5x the cost)
    const double du = spots[b].u - spots[a].u, dv = spots[b].v - spots[a].v;
    return std::sqrt(du * du + dv * dv);
  };
  const auto similar = [&](double a, double b) { return a < step_ratio * b && b < step_ratio * a; };
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 4; ++k) {
      const int j = mutual[i][k];
      if (j < 0) continue;
      const double len = length(static_cast<int>(i), j);
      const int before = mutual[i][(k + 2) % 4];
      const int after = mutual[j][k];
      const bool comparable = before >= 0 || after >= 0;
      const bool regular = (before >= 0 && similar(len, length(static_cast<int>(i), before))) ||
                           (after >= 0 && similar(len, length(j, after)));
      if (!comparable || regular) g.next[i][k] = j;
    }
  // keep the graph symmetric: a link dropped on one side is dropped on the other
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 4; ++k) {
      const int j = g.next[i][k];
      if (j >= 0 && g.next[j][(k + 2) % 4] != static_cast<int>(i)) g.next[i][k] = -1;
    }
}

}  // namespace

AdjacencyGraph build_adjacency(const std::vector<Spot>& spots, bool mend, const AdjacencyOptions& o,
                               const CellShape& shape) {
  AdjacencyGraph g;
  const std::size_t n = spots.size();
  g.next.assign(n, {-1, -1, -1, -1});
  if (n < 2) return g;
  const std::vector<double> nn_dist = nearest_distances(spots, g.grid_angle_rad);
  const double spacing = median(nn_dist);
  const SpatialGrid near(spots, std::max(2.0, spacing));
  keep_regular_links(spots, link_candidates(spots, near, nn_dist, spacing, g.grid_angle_rad, o), shape.step_ratio, g);
  if (!mend) return g;
  align_chains(g, kEast, kSouth, o);  // columns between row chains
  complete_links(g, spots, near, o.completion_slack);
  return g;
}

Neighbourhoods check_graph_consistency(const AdjacencyGraph& g) {
  Neighbourhoods h;
  const std::size_t n = g.next.size();
  h.window.assign(n, Window{-1, -1, -1, -1, -1, -1, -1, -1, -1});
  const auto step = [&](int i, Direction d) { return i < 0 ? -1 : g.next[i][d]; };
  // both ways round the corner must reach the same spot
  const auto corner = [&](int i, Direction a, Direction b) {
    const int p = step(step(i, a), b), q = step(step(i, b), a);
    return p >= 0 && p == q ? p : -1;
  };
  for (std::size_t s = 0; s < n; ++s) {
    const int i = static_cast<int>(s);
    Window& w = h.window[s];
    w[1] = g.next[s][kNorth];
    w[3] = g.next[s][kWest];
    w[4] = i;
    w[5] = g.next[s][kEast];
    w[7] = g.next[s][kSouth];
    w[0] = corner(i, kNorth, kWest);
    w[2] = corner(i, kNorth, kEast);
    w[6] = corner(i, kSouth, kWest);
    w[8] = corner(i, kSouth, kEast);
  }
  return h;
}

}  // namespace vision
