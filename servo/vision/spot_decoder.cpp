#include "servo/vision/spot_decoder.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <tuple>

namespace vision {
namespace {

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
  }
  template <typename F>
  void around(double u, double v, int reach, F&& f) const {
    const int cu = static_cast<int>((u - origin_u_) / cell_), cv = static_cast<int>((v - origin_v_) / cell_);
    for (int r = std::max(0, cv - reach); r <= std::min(rows_ - 1, cv + reach); ++r)
      for (int c = std::max(0, cu - reach); c <= std::min(cols_ - 1, cu + reach); ++c) {
        const std::size_t k = static_cast<std::size_t>(r) * cols_ + c;
        for (int i = start_[k]; i < start_[k + 1]; ++i) f(index_[i]);
      }
  }

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
};

double median(std::vector<double> x) {
  if (x.empty()) return 0;
  std::nth_element(x.begin(), x.begin() + x.size() / 2, x.end());
  return x[x.size() / 2];
}

}  // namespace

namespace {

// Rows are linked far more reliably than columns (the spacing along a row is regular; down a
// column, shear and foreshortening make a diagonal neighbour compete with the true one). Two
// rows of the pattern that lie one above the other are joined by one column offset: the links
// between two row chains vote for it, and when most agree, every spot of the two chains is
// linked by it (a link the nearest-spot rule got wrong or missed is mended). Which offset is
// the pattern's own, not a shear of it, the code decides later (resolve_column_shear).
void align_chains(AdjacencyGraph& g, Direction along, Direction across) {
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
  // per chain pair: the offset most links take, when at least 3 and three quarters of them do
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
    if (best >= 3 && 4 * best >= 3 * total) joins.push_back({votes[a].upper, votes[a].lower, best_offset});
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

// how far (fraction of a step) a completed link's spot may be from where its neighbours put it
constexpr double kCompletionSlack = 0.3;

// Completion from the lattice around: a link the nearest-candidate rule missed (a column whose
// candidates two spots contend for, a row squeezed towards the silhouette past the spacing
// rule) is where the neighbours' links say it is. The spot missing its south link takes the
// step its east and west neighbours take south, and links the spot found there if that one
// has no north link yet. Two rounds: a completed link lends its step to the next.
void complete_links(AdjacencyGraph& g, const std::vector<Spot>& spots, const SpatialGrid& near) {
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
        double best = kCompletionSlack * kCompletionSlack * step2;
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
    grid.around(spots[i].u, spots[i].v, 2, [&](int j) {
      if (j == static_cast<int>(i)) return;
      const double du = spots[j].u - spots[i].u, dv = spots[j].v - spots[i].v;
      const double d2 = du * du + dv * dv;  // squared: std::hypot is ten times dearer and not needed
      if (d2 < best) best = d2, bj = j;
    });
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

// The candidate east, south, west and north neighbours of every spot.
std::vector<std::array<int, 4>> link_candidates(const std::vector<Spot>& spots, const SpatialGrid& near,
                                                const std::vector<double>& nn_dist, double spacing,
                                                double grid_angle_rad) {
  const std::size_t n = spots.size();
  // Rows first: the closest spot within +-35 deg of the pattern's east and west. Then columns,
  // against each spot's own row direction: under perspective the columns shear away from the
  // perpendicular and a diagonal neighbour can be nearer than the true one, so the north and
  // south candidates are ranked by distance weighted by their angle to the local perpendicular.
  std::vector<std::array<int, 4>> cand(n, {-1, -1, -1, -1});
  struct Candidate {
    int j;
    double du, dv, d2;  // squared distance: the square root only for the few in a cone
  };
  std::vector<Candidate> around;  // one spot's neighbours within reach, gathered once for both passes
  const double row_cos = std::cos(35.0 * kPi / 180.0);
  const double col_cos = std::cos(45.0 * kPi / 180.0);
  const double row_cos2 = row_cos * row_cos, col_cos2 = col_cos * col_cos;
  const double ce = std::cos(grid_angle_rad), se = std::sin(grid_angle_rad);
  for (std::size_t i = 0; i < n; ++i) {
    const double reach = 3.5 * std::max(nn_dist[i], 0.5 * spacing);
    const double reach2 = reach * reach;
    around.clear();
    near.around(spots[i].u, spots[i].v, static_cast<int>(std::ceil(reach / std::max(2.0, spacing))), [&](int j) {
      const double du = spots[j].u - spots[i].u, dv = spots[j].v - spots[i].v;
      const double d2 = du * du + dv * dv;
      if (d2 <= reach2 && d2 > 1e-18) around.push_back({j, du, dv, d2});  // (j == i has d2 = 0)
    });
    // rows: cos >= row_cos, i.e. dot >= 0 and dot^2 >= row_cos^2 d^2
    std::array<double, 2> best{1e300, 1e300};
    for (const Candidate& c : around) {
      const double dot = c.du * ce + c.dv * se;
      if (dot * dot < row_cos2 * c.d2) continue;
      const int side = dot > 0 ? 0 : 1;
      if (c.d2 < best[side]) best[side] = c.d2, cand[i][side == 0 ? kEast : kWest] = c.j;
    }
    // this spot's row direction, from its east and west candidates when it has them
    double ru = ce, rv = se;
    const int e = cand[i][kEast], w = cand[i][kWest];
    if (e >= 0 || w >= 0) {
      ru = rv = 0;
      for (const auto& [j, sign] : {std::pair{e, 1.0}, std::pair{w, -1.0}}) {
        if (j < 0) continue;
        const double du = spots[j].u - spots[i].u, dv = spots[j].v - spots[i].v, d = std::sqrt(du * du + dv * dv);
        ru += sign * du / d;
        rv += sign * dv / d;
      }
      const double norm = std::sqrt(ru * ru + rv * rv);
      ru /= norm, rv /= norm;
    }
    // columns
    const double pu = -rv, pv = ru;  // the perpendicular, pointing south (image y down)
    best = {1e300, 1e300};
    for (const Candidate& c : around) {
      const double dot = c.du * pu + c.dv * pv;
      if (dot * dot < col_cos2 * c.d2) continue;
      const double d = std::sqrt(c.d2);
      const double cosine = std::min(1.0, std::abs(dot) / d);
      // ~ d (1 + 2 angle): sqrt(2 (1 - cos)) is the angle to within 4 % below 45 deg, sans acos
      const double score = d * (1.0 + 2.0 * std::sqrt(2.0 * (1.0 - cosine)));
      if (dot > 0 && score < best[0]) best[0] = score, cand[i][kSouth] = c.j;
      if (dot < 0 && score < best[1]) best[1] = score, cand[i][kNorth] = c.j;
    }
  }
  return cand;
}

// The links kept: mutual candidates, regularly spaced, symmetric.
void keep_regular_links(const std::vector<Spot>& spots, const std::vector<std::array<int, 4>>& cand,
                        AdjacencyGraph& g) {
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
  const auto length = [&](int a, int b) { return std::hypot(spots[b].u - spots[a].u, spots[b].v - spots[a].v); };
  const auto similar = [](double a, double b) { return a < 1.5 * b && b < 1.5 * a; };
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

AdjacencyGraph build_adjacency(const std::vector<Spot>& spots, bool mend) {
  AdjacencyGraph g;
  const std::size_t n = spots.size();
  g.next.assign(n, {-1, -1, -1, -1});
  if (n < 2) return g;
  const std::vector<double> nn_dist = nearest_distances(spots, g.grid_angle_rad);
  const double spacing = median(nn_dist);
  const SpatialGrid near(spots, std::max(2.0, spacing));
  keep_regular_links(spots, link_candidates(spots, near, nn_dist, spacing, g.grid_angle_rad), g);
  if (!mend) return g;
  align_chains(g, kEast, kSouth);  // columns between row chains
  complete_links(g, spots, near);
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

EpipolarCheck::EpipolarCheck(const EpipolarGeometry& g, const std::vector<Spot>& spots) : geometry(g) {
  xy.reserve(spots.size());
  for (const Spot& s : spots) xy.push_back(g.normalise(s.u, s.v));
}

bool EpipolarCheck::confirms(const Window& w, const pattern::SpotId& centre) const {
  for (int i = 0; i < 9; ++i)
    if (w[i] >= 0 && !confirms(w[i], {centre.row + i / 3 - 1, centre.col + i % 3 - 1})) return false;
  return true;
}

namespace {
// how much a run's step may change from one spot to the next (fraction of the step)
constexpr double kRunBend = 0.4;

// Three spots a, b, c in a row of the lattice on one smooth surface: the step b -> c close to
// a -> b. Across a depth edge the spot from the surface behind breaks it.
bool bends_little(const Spot& a, const Spot& b, const Spot& c) {
  const double su = c.u - 2 * b.u + a.u, sv = c.v - 2 * b.v + a.v;
  const double lu = c.u - b.u, lv = c.v - b.v, pu = b.u - a.u, pv = b.v - a.v;
  return su * su + sv * sv <= kRunBend * kRunBend * std::max(lu * lu + lv * lv, pu * pu + pv * pv);
}

// how unlike (fraction of the step) the opposite sides of a window's lattice cell may be
constexpr double kCellSlack = 0.35;

// every row and column of the window (where all three spots are there) bends little, and each
// of its four lattice cells is near a parallelogram: a cell across a depth edge, with a spot
// from the surface behind shifted along its row, is not
bool smooth_window(const std::vector<Spot>& spots, const Window& w) {
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
      if (du * du + dv * dv > kCellSlack * kCellSlack * std::max(step2, 0.25 * side2)) return false;
    }
  for (int k = 0; k < 3; ++k) {
    const int r0 = w[3 * k], r1 = w[3 * k + 1], r2 = w[3 * k + 2];
    if (r0 >= 0 && r1 >= 0 && r2 >= 0 && !bends_little(spots[r0], spots[r1], spots[r2])) return false;
    const int c0 = w[k], c1 = w[k + 3], c2 = w[k + 6];
    if (c0 >= 0 && c1 >= 0 && c2 >= 0 && !bends_little(spots[c0], spots[c1], spots[c2])) return false;
  }
  return true;
}

// the colours of a window whose nine spots are all there, or nothing
std::optional<std::array<std::uint8_t, 9>> colours_of(const std::vector<Spot>& spots, const Window& w) {
  std::array<std::uint8_t, 9> c{};
  for (int i = 0; i < 9; ++i) {
    if (w[i] < 0) return std::nullopt;
    c[i] = static_cast<std::uint8_t>(spots[w[i]].colour);
  }
  return c;
}
// the window is whole, smooth and reads as a pattern window (on its epipolar lines when checked)
bool reads(const std::vector<Spot>& spots, const Window& w, const pattern::WindowTable& table,
           const EpipolarCheck* check) {
  const auto c = colours_of(spots, w);
  if (!c) return false;
  const auto id = table.find(c->data());  // the code first: it is cheaper than the geometry
  return id && smooth_window(spots, w) && (!check || check->confirms(w, *id));
}

// a blob smaller than this fraction of the median area of the spots linked to it is a fragment
constexpr double kFragmentArea = 0.5;

bool is_fragment(const std::vector<Spot>& spots, const AdjacencyGraph& graph, int i) {
  std::array<int, 4> areas{};
  std::size_t m = 0;
  for (const int j : graph.next[i])
    if (j >= 0) areas[m++] = spots[j].area_px;
  if (m == 0) return false;
  for (std::size_t a = 1; a < m; ++a)  // insertion sort of at most four
    for (std::size_t b = a; b > 0 && areas[b - 1] > areas[b]; --b) std::swap(areas[b - 1], areas[b]);
  const double median = m % 2 ? areas[m / 2] : 0.5 * (areas[m / 2 - 1] + areas[m / 2]);
  return spots[i].area_px < kFragmentArea * median;
}

}  // namespace

namespace {

// The line through t, m, b (before, the spot, after) goes straight on: a shear slants it,
// curvature bends it a little; its two steps are alike in length.
bool goes_straight(const Spot& t, const Spot& m, const Spot& b) {
  const double eu = t.u + b.u - 2 * m.u, ev = t.v + b.v - 2 * m.v;
  const double lt = (t.u - m.u) * (t.u - m.u) + (t.v - m.v) * (t.v - m.v);
  const double lb = (b.u - m.u) * (b.u - m.u) + (b.v - m.v) * (b.v - m.v);
  return eu * eu + ev * ev <= 0.16 * std::max(lt, lb) && lt <= 2.25 * lb && lb <= 2.25 * lt;
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
                             const pattern::WindowTable& table, const EpipolarCheck* check, ShearAxis axis) {
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
    if (reads(spots, hoods.window[s], table, check)) continue;  // its links read already
    const auto middle = line_of(i);
    if (!middle) continue;
    const int nt = centres(i, reverse, befores), nb = centres(i, across, afters);
    int matches = 0;
    std::array<int, 2> best{-1, -1};
    for (int a = 0; a < nt && matches <= 1; ++a)
      for (int b = 0; b < nb && matches <= 1; ++b) {
        const int t = befores[a], u = afters[b];
        if (t == u) continue;
        if (!goes_straight(spots[t], spots[i], spots[u])) continue;
        const auto first = line_of(t), last = line_of(u);
        if (!first || !last) continue;
        Window w{};
        for (int k = 0; k < 3; ++k) {
          w[cell(0, k)] = (*first)[k];
          w[cell(1, k)] = (*middle)[k];
          w[cell(2, k)] = (*last)[k];
        }
        if (!reads(spots, w, table, check)) continue;
        ++matches;
        best = {t, u};
      }
    if (matches != 1 || (best[0] == graph.next[s][reverse] && best[1] == graph.next[s][across])) continue;
    proposal[s] = best;
    proposed[s] = 1;
  }
  return apply_shear_choices(graph, proposal, proposed, along, across);
}

std::vector<WindowReading> read_windows(const std::vector<Spot>& spots, const Neighbourhoods& hoods,
                                        const pattern::WindowTable& table, const ToleranceOptions& tolerance,
                                        const EpipolarCheck* check) {
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
      if (smooth < 0) smooth = smooth_window(spots, w);
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

void add_window_votes(const Neighbourhoods& hoods, const std::vector<WindowReading>& readings,
                      std::vector<IdVote>& votes) {
  for (const WindowReading& r : readings) {
    const Window& w = hoods.window[r.centre];
    for (int i = 0; i < 9; ++i)
      if (w[i] >= 0 && i != r.wrong)  // the misread spot of a corrected window gets no vote from it
        votes.push_back({w[i], {r.id.row + i / 3 - 1, r.id.col + i % 3 - 1}, r.corrected});
  }
}

// how far (fraction of a lattice step) a propagated spot may be from where the lattice puts it
constexpr double kLatticeSlack = 0.25;


void read_segments(const std::vector<Spot>& spots, const AdjacencyGraph& graph, const EpipolarCheck& check,
                   const pattern::MArray& pattern, int length, std::vector<IdVote>& votes) {
  const int half = length / 2;
  if (half < 1) return;
  // the ids each spot may carry: its colour, on its epipolar line (a handful of the 400)
  std::vector<std::vector<pattern::SpotId>> by_colour(static_cast<std::size_t>(pattern.colours));
  for (int r = 0; r < pattern.rows; ++r)
    for (int c = 0; c < pattern.cols; ++c) by_colour[pattern.at(r, c)].push_back({r, c});
  std::vector<std::vector<pattern::SpotId>> candidates(spots.size());
  const auto candidates_of = [&](int i) -> const std::vector<pattern::SpotId>& {
    auto& out = candidates[i];
    if (out.empty() && spots[i].colour >= 0 && spots[i].colour < pattern.colours)
      for (const pattern::SpotId& id : by_colour[spots[i].colour])
        if (check.confirms(i, id)) out.push_back(id);
    return out;
  };
  std::vector<int> run(static_cast<std::size_t>(2 * half + 1));
  for (const auto& [forward, back, dr, dc] : {std::tuple{kEast, kWest, 0, 1}, std::tuple{kSouth, kNorth, 1, 0}}) {
    for (std::size_t s = 0; s < spots.size(); ++s) {
      // the run centred on s, `half` links each way
      run[half] = static_cast<int>(s);
      bool whole = true;
      for (int m = 1; m <= half && whole; ++m) {
        run[half + m] = graph.next[run[half + m - 1]][forward];
        run[half - m] = graph.next[run[half - m + 1]][back];
        whole = run[half + m] >= 0 && run[half - m] >= 0;
      }
      if (!whole) continue;
      // a run along one surface is smooth: each step close to the one before. At an object's
      // edge the run jumps to the surface behind, whose spot can sit on the same epipolar line
      bool smooth = true;
      for (int m = 1; m + 1 < 2 * half + 1 && smooth; ++m)
        smooth = bends_little(spots[run[m - 1]], spots[run[m]], spots[run[m + 1]]);
      if (!smooth) continue;
      // the run read straight along the axis, or sheared by one id across it per step (a
      // column seen obliquely links diagonal neighbours): a misread run that fits one way
      // while the truth fits another is ambiguous, and dropped
      int matches = 0;
      pattern::SpotId found{};
      int found_shear = 0;
      for (const pattern::SpotId& a : candidates_of(static_cast<int>(s)))
        for (int shear = -1; shear <= 1 && matches <= 1; ++shear) {
          bool fits = true;
          for (int m = -half; m <= half && fits; ++m) {
            if (m == 0) continue;
            const pattern::SpotId id{a.row + m * dr + shear * m * dc, a.col + m * dc + shear * m * dr};
            fits = id.row >= 0 && id.col >= 0 && id.row < pattern.rows && id.col < pattern.cols &&
                   pattern.at(id.row, id.col) == spots[run[half + m]].colour && check.confirms(run[half + m], id);
          }
          if (fits && ++matches == 1) found = a, found_shear = shear;
        }
      if (matches != 1) continue;
      for (int m = -half; m <= half; ++m)
        votes.push_back({run[half + m],
                         {found.row + m * dr + found_shear * m * dc, found.col + m * dc + found_shear * m * dr}});
    }
  }
}

std::vector<DecodedSpot> check_vote_consistency(const std::vector<Spot>& spots, const std::vector<IdVote>& votes,
                                                int min_votes, bool two_exact) {
  struct Tally {
    pattern::SpotId id{-1, -1};
    int count = 0, exact = 0;
    bool conflict = false;
  };
  std::vector<Tally> tally(spots.size());
  int rows = 0, cols = 0;
  for (const IdVote& v : votes) {
    Tally& t = tally[v.spot];
    if (t.count == 0) t.id = v.id;
    else if (!(t.id == v.id)) t.conflict = true;
    ++t.count;
    t.exact += !v.repaired;
    rows = std::max(rows, v.id.row + 1), cols = std::max(cols, v.id.col + 1);
  }
  // an id claimed by two spots is kept by neither
  std::vector<int> owners(static_cast<std::size_t>(rows) * cols, 0);
  const auto owner = [&](const pattern::SpotId& id) -> int& { return owners[static_cast<std::size_t>(id.row) * cols + id.col]; };
  // repaired windows (corrected, completed) add votes and veto, but a spot that no exact
  // window names is not named: at a depth edge a window read across two surfaces, columns
  // shifted by one and one colour off, is the shifted window at distance 1, and repairs alone
  // backed its shifted id (4 wrong ids in 1000 ham poses with the distance-3 pattern, issue 19)
  const auto named = [&](const Tally& t) {
    return !t.conflict && ((t.count >= min_votes && t.exact > 0) || (two_exact && t.count == 2 && t.exact == 2));
  };
  for (std::size_t s = 0; s < spots.size(); ++s)
    if (named(tally[s])) ++owner(tally[s].id);
  std::vector<DecodedSpot> out;
  for (std::size_t s = 0; s < spots.size(); ++s) {
    const Tally& t = tally[s];
    if (!named(t) || owner(t.id) != 1) continue;
    out.push_back({t.id.row, t.id.col, spots[s].u, spots[s].v, static_cast<int>(s)});
  }
  return out;
}

std::vector<DecodedSpot> check_decoding_consistency(const std::vector<Spot>& spots, const Neighbourhoods& hoods,
                                                    const std::vector<WindowReading>& readings, int min_votes) {
  std::vector<IdVote> votes;
  votes.reserve(readings.size() * 9);
  add_window_votes(hoods, readings, votes);
  return check_vote_consistency(spots, votes, min_votes);
}

namespace {
// Islands of decoded spots: the components of the graph's links between decoded spots that
// `joins(i, j, k)` accepts (i, j indices into the decoded list, k the link's direction).
struct Islands {
  std::vector<int> of;    // decoded index -> island, -1 where `member` excluded it
  std::vector<int> size;  // spots per island
};
template <typename Member, typename Joins>
Islands find_islands(const AdjacencyGraph& graph, const std::vector<DecodedSpot>& decoded, const std::vector<int>& at,
                     Member&& member, Joins&& joins) {
  Islands islands;
  islands.of.assign(decoded.size(), -1);
  std::vector<int> stack;
  for (std::size_t s = 0; s < decoded.size(); ++s) {
    if (!member(static_cast<int>(s)) || islands.of[s] >= 0) continue;
    const int id = static_cast<int>(islands.size.size());
    islands.size.push_back(0);
    stack.assign(1, static_cast<int>(s));
    islands.of[s] = id;
    while (!stack.empty()) {
      const int i = stack.back();
      stack.pop_back();
      ++islands.size[id];
      for (int k = 0; k < 4; ++k) {
        const int j = graph.next[decoded[i].spot][k];
        if (j < 0 || at[j] < 0 || islands.of[at[j]] >= 0 || !member(at[j]) || !joins(i, at[j], k)) continue;
        islands.of[at[j]] = id;
        stack.push_back(at[j]);
      }
    }
  }
  return islands;
}
}  // namespace

std::vector<DecodedSpot> check_island_consistency(const AdjacencyGraph& graph, std::vector<DecodedSpot> decoded,
                                                  int spot_count, int min_island, bool sheared_links) {
  std::vector<int> at(static_cast<std::size_t>(spot_count), -1);  // spot -> index in decoded
  for (std::size_t i = 0; i < decoded.size(); ++i) at[decoded[i].spot] = static_cast<int>(i);
  const auto agrees = [&](const DecodedSpot& a, const DecodedSpot& b, int k) {
    const int dr = b.row - a.row - kIdStep[k][0], dc = b.col - a.col - kIdStep[k][1];
    if (dr == 0 && dc == 0) return true;
    // a sheared link: one step along k and one across it
    return sheared_links && (kIdStep[k][0] == 0 ? (dc == 0 && std::abs(dr) == 1) : (dr == 0 && std::abs(dc) == 1));
  };
  const auto all = [](int) { return true; };
  // The regions the agreeing links join, before any spot is condemned. A link whose ids
  // disagree condemns both its spots, unless it joins two such regions of min_island spots or
  // more: that is two surfaces meeting at a depth edge, the nearest-spot rule linking across
  // it (the ham's silhouette row over the table's lattice), and the link is what is wrong. A
  // misread spot or patch has no such region of its own: its links to the right ids around
  // it disagree.
  const Islands regions = find_islands(graph, decoded, at, all, [&](int i, int j, int k) {
    return agrees(decoded[i], decoded[j], k);
  });
  const auto large = [&](int i) { return regions.size[regions.of[i]] >= min_island; };
  std::vector<char> keep(decoded.size(), 1);
  for (std::size_t i = 0; i < decoded.size(); ++i)
    for (int k = 0; k < 4; ++k) {
      const int j = graph.next[decoded[i].spot][k];
      if (j < 0 || at[j] < 0 || agrees(decoded[i], decoded[at[j]], k)) continue;
      if (min_island > 0 && regions.of[i] != regions.of[at[j]] && large(static_cast<int>(i)) && large(at[j])) continue;
      keep[i] = keep[at[j]] = 0;
    }
  // islands of id-consistent linked spots
  const Islands islands = find_islands(graph, decoded, at, [&](int i) { return keep[i] != 0; },
                                       [](int, int, int) { return true; });
  std::vector<DecodedSpot> out;
  for (std::size_t i = 0; i < decoded.size(); ++i)
    if (keep[i] && islands.size[islands.of[i]] >= min_island) out.push_back(decoded[i]);
  return out;
}

namespace {

// how much fainter or smaller than its source a propagated spot may be
constexpr double kAlike = 0.4;
bool alike(const Spot& source, const Spot& s) {
  return s.strength >= kAlike * source.strength && s.area_px >= kAlike * source.area_px;
}

// Which spot carries each id, and where each identified spot is in the decoded list: the
// bookkeeping of the steps that name spots one at a time (propagation, growth).
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

// Spot j may take id X: the pattern has its colour at X, it lies on X's epipolar line, and no
// free id around X (`taken(row, col)` false) fits it as well: a step that skipped a missing
// spot or crossed a sheared column would otherwise pass an id on shifted by one.
template <typename Taken>
bool only_fitting_id(const std::vector<Spot>& spots, int j, const pattern::SpotId& x, const EpipolarCheck& check,
                     const pattern::MArray& pattern, Taken&& taken) {
  const auto fits = [&](int r, int c) { return pattern.at(r, c) == spots[j].colour && check.confirms(j, {r, c}); };
  if (!fits(x.row, x.col)) return false;
  for (int dr = -1; dr <= 1; ++dr)
    for (int dc = -1; dc <= 1; ++dc) {
      const int r = x.row + dr, c = x.col + dc;
      if ((dr == 0 && dc == 0) || r < 0 || c < 0 || r >= pattern.rows || c >= pattern.cols || taken(r, c)) continue;
      if (fits(r, c)) return false;
    }
  return true;
}

}  // namespace

std::vector<DecodedSpot> propagate_ids(const std::vector<Spot>& spots, const AdjacencyGraph& graph,
                                       const Neighbourhoods& hoods, const EpipolarCheck& check,
                                       const pattern::MArray& pattern, std::vector<DecodedSpot> decoded,
                                       int min_sources) {
  IdMap ids(pattern, spots.size(), decoded);
  const auto spot_at = [&](int r, int c) { return ids.spot_at(r, c); };
  const auto continues_lattice = [&](const DecodedSpot& from, int j, int k) {
    const int dr = kIdStep[k][0], dc = kIdStep[k][1];
    // reference steps in k: behind the source, then beside it (either side)
    const std::array<std::pair<int, int>, 3> refs{{{spot_at(from.row - dr, from.col - dc), from.spot},
                                                  {spot_at(from.row + dc, from.col + dr),
                                                   spot_at(from.row + dc + dr, from.col + dr + dc)},
                                                  {spot_at(from.row - dc, from.col - dr),
                                                   spot_at(from.row - dc + dr, from.col - dr + dc)}}};
    for (const auto& [a, b] : refs) {
      if (a < 0 || b < 0) continue;
      const double vu = spots[b].u - spots[a].u, vv = spots[b].v - spots[a].v;
      const double eu = spots[j].u - spots[from.spot].u - vu, ev = spots[j].v - spots[from.spot].v - vv;
      return eu * eu + ev * ev <= kLatticeSlack * kLatticeSlack * (vu * vu + vv * vv);
    }
    return false;  // nothing to compare with: not propagated
  };
  // The spot linked beyond j, if any, must go on with the lattice and the pattern: at an
  // object's edge, the spot that sits where the lattice goes on belongs to the surface behind,
  // and the one beyond it follows that surface's spacing, not this one's.
  const auto beyond_agrees = [&](const DecodedSpot& from, int j, int k, const pattern::SpotId& id) {
    const int b = graph.next[j][k];
    if (b < 0) return true;
    const pattern::SpotId next{id.row + kIdStep[k][0], id.col + kIdStep[k][1]};
    if (ids.index_of(b) >= 0) return decoded[ids.index_of(b)].row == next.row && decoded[ids.index_of(b)].col == next.col;
    if (next.row < 0 || next.col < 0 || next.row >= pattern.rows || next.col >= pattern.cols) return false;
    if (pattern.at(next.row, next.col) != spots[b].colour) return false;
    const double vu = spots[j].u - spots[from.spot].u, vv = spots[j].v - spots[from.spot].v;
    const double eu = spots[b].u - spots[j].u - vu, ev = spots[b].v - spots[j].v - vv;
    return eu * eu + ev * ev <= kLatticeSlack * kLatticeSlack * (vu * vu + vv * vv);
  };
  // In rounds: an undecoded spot takes an id when at least `min_sources` decoded spots around
  // it (one of them linked) propose the same id (and none proposes another).
  struct Proposal {
    pattern::SpotId id{-1, -1};
    int sources = 0;
    bool conflict = false;
  };
  std::vector<Proposal> proposals(spots.size());
  for (bool grew = true; grew;) {
    grew = false;
    std::fill(proposals.begin(), proposals.end(), Proposal{});
    for (const DecodedSpot& from : decoded)
      for (int k = 0; k < 4; ++k) {
        const int j = graph.next[from.spot][k];
        if (j < 0 || ids.index_of(j) >= 0 || spots[j].truncated) continue;
        const pattern::SpotId id{from.row + kIdStep[k][0], from.col + kIdStep[k][1]};
        Proposal& p = proposals[j];
        if (!continues_lattice(from, j, k)) continue;  // j is not where this source's lattice goes
        // j looks like a spot of the source's surface: a faint speck of noise, or the dim light
        // of a surface behind an edge (defocused, oblique), is not
        if (!alike(spots[from.spot], spots[j])) continue;
        if (!beyond_agrees(from, j, k, id)) continue;
        if (p.sources > 0 && !(p.id == id)) p.conflict = true;
        p.id = id;
        ++p.sources;
      }
    // decoded diagonal neighbours (corners that both paths round agree on) second a proposal:
    // a spot beyond a decoded edge has its one linked source and two corners
    for (std::size_t j = 0; j < spots.size(); ++j) {
      Proposal& p = proposals[j];
      if (p.sources == 0 || p.conflict) continue;
      for (const int i : {0, 2, 6, 8}) {
        const int q = hoods.window[j][i];
        if (q < 0 || ids.index_of(q) < 0) continue;
        const DecodedSpot& d = decoded[ids.index_of(q)];
        const pattern::SpotId id{d.row - (i / 3 - 1), d.col - (i % 3 - 1)};
        if (!(p.id == id)) p.conflict = true;
        ++p.sources;
      }
    }
    for (std::size_t j = 0; j < spots.size(); ++j) {
      const Proposal& p = proposals[j];
      if (p.conflict || p.sources < min_sources) continue;
      const int r = p.id.row, c = p.id.col;
      if (!ids.inside(r, c) || ids.taken(r, c)) continue;
      if (!only_fitting_id(spots, static_cast<int>(j), p.id, check, pattern, [&](int rr, int cc) { return ids.taken(rr, cc); }))
        continue;
      decoded.push_back({r, c, spots[j].u, spots[j].v, static_cast<int>(j)});
      ids.add(decoded.back(), static_cast<int>(decoded.size()) - 1);
      grew = true;
    }
  }
  return decoded;
}

namespace {
// how far (fraction of a lattice step) a grown spot may be from where the lattice puts it:
// wider than a propagated link's (0.25), as the prediction may reach across a missing link and
// the step changes fast on the oblique flanks. 0.45 (was 0.35): +0.4 points of the ham's
// readable spots, +0.6 of the cylinder's, the same wrong ids in 24 sweeps of 1000 poses; 0.55
// names fewer (a farther spot wins the place)
constexpr double kGrowSlack = 0.45;
// a grown spot no bigger than this many times any source: a wider blob is the colour wash of a
// surface far out of focus behind a silhouette, not a spot
constexpr double kGrowLargest = 2.5;
// A spot named from a single row or column neighbour (and corners) must look like its sources'
// mean: at a silhouette the prediction can fall on a speck or a faint wash blob. Set on 1000-pose
// sweeps of the cylinder behind an occluder, the scenario that showed such wrong ids.
constexpr double kGrowDimmest = 0.6, kGrowAreaBelow = 0.6, kGrowAreaAbove = 1.7;
constexpr int kGrowSmallestPx = 10;
// nor barely above the segmentation's threshold (mean chroma above it, 8-bit levels): the dim
// glow at a silhouette, a spot of another row compressed there (1 wrong id in 1000 poses of
// `cylinder_occlusion`'s widened draw); 0.2 % of the right ones are as faint
constexpr float kGrowFaintest = 5.0F;
// A single source naming another id is outvoted by this many more sources than it. Until now any
// dissent left the spot unnamed: in 1000 ham poses, 1 683 spots that colour, epipolar line and
// uniqueness would have named right. Outvoting one dissent by 2: +0.6 points of the ham's
// readable spots, the same wrong ids in 24 calibrated sweeps; two dissents by 1: +0.1 more.
constexpr int kGrowMajority = 2;
// One source fewer than asked names a spot when every source's step lands within this fraction
// of a step of the blob (the prediction a quarter as loose as kGrowSlack) and the blob looks like
// its sources. At a silhouette only two identified spots may touch the next one (a row or
// column neighbour and a corner); what fell at a depth edge within 0.2 of a step was the surface
// behind's spot, never one within 0.12. +0.3 points of the ham's readable spots, +0.5 of the
// cylinder's, the same wrong ids in 32 calibrated sweeps of 1000 poses.
constexpr double kGrowTightSlack = 0.12;
// Or when the row or column neighbour's step lands on the blob's line (within 0.08 of a step
// aside) at 0.85-1.2 of its length, the corner's within kGrowSlack: towards a silhouette the
// surface turns away and the last step shrinks or stretches along itself (the ham's first and
// last columns), and the corner's prediction, two steps, drifts by 0.2-0.4. Along a row the
// epipolar line cannot tell a column from another, so the blob of the surface behind can lie on
// the step's line: the one such wrong id seen (1000 cylinder poses) lay at 0.75 of the step,
// 0.45 as strong as its sources. A spot named one short is at least half as strong as them.
// +0.2 points of the ham's readable spots, the same wrong ids in 32 calibrated sweeps.
constexpr double kGrowOnLineAside = 0.08, kGrowOnLineShortest = 0.85, kGrowOnLineLongest = 1.2;
constexpr double kGrowOneShortDimmest = 0.5;
// A spot the lattice pins (three sources or more, two of them row or column neighbours, each
// within kGrowTightSlack) needs no uniqueness among the ids around it: along a row the epipolar
// lines coincide, so a row's neighbour of the same colour fits as well as the id itself one time
// in three, and such spots were refused however many sources agreed (the table at the
// pattern's corner, the ham's flanks). Ham 89.7 -> 90.3 % of its readable spots, 64.8 -> 65.4 %
// of its visible ones; the same wrong ids in 32 calibrated sweeps of 1000 poses.
constexpr int kGrowPinnedSources = 3;

// The spots on a grid whose cells are a lattice step wide (the median length of the graph's
// links); none without a link.
std::optional<SpatialGrid> lattice_grid(const std::vector<Spot>& spots, const AdjacencyGraph& graph) {
  std::vector<double> lengths;
  for (std::size_t s = 0; s < spots.size(); ++s)
    for (const int k : {kEast, kSouth})
      if (const int j = graph.next[s][k]; j >= 0) lengths.push_back(std::hypot(spots[j].u - spots[s].u, spots[j].v - spots[s].v));
  if (lengths.empty()) return std::nullopt;
  return SpatialGrid(spots, std::max(2.0, median(lengths)));
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
}  // namespace

std::vector<DecodedSpot> grow_lattice(const std::vector<Spot>& spots, AdjacencyGraph& graph,
                                      const EpipolarCheck& check, const pattern::MArray& pattern,
                                      std::vector<DecodedSpot> decoded, int min_sources) {
  const std::size_t n = spots.size();
  if (decoded.empty() || n < 2) return decoded;
  IdMap ids(pattern, n, decoded);
  const auto spot_at = [&](int r, int c) { return ids.spot_at(r, c); };
  const std::optional<SpatialGrid> near = lattice_grid(spots, graph);
  if (!near) return decoded;
  // The lattice step (dr, dc) at the identified spot (r, c), from identified spots only: ahead
  // of it, behind it, or beside it (the next row or column), the nearest first.
  const auto lattice_step = [&](int r, int c, int dr, int dc, double& vu, double& vv) {
    const std::array<std::pair<int, int>, 4> refs{{{spot_at(r, c), spot_at(r + dr, c + dc)},
                                                  {spot_at(r - dr, c - dc), spot_at(r, c)},
                                                  {spot_at(r + dc, c + dr), spot_at(r + dc + dr, c + dr + dc)},
                                                  {spot_at(r - dc, c - dr), spot_at(r - dc + dr, c - dr + dc)}}};
    for (const auto& [a, b] : refs)
      if (a >= 0 && b >= 0) {
        vu = spots[b].u - spots[a].u, vv = spots[b].v - spots[a].v;
        return true;
      }
    return false;
  };
  // The claims on one spot: the id most sources name, and the one other id (if any) that some
  // source names instead. On a curved surface one source's step can be a little off and place
  // its neighbour's id on the spot; one such dissent against `kGrowMajority` more agreeing sources
  // is outvoted, a second dissenting source or a third id leaves the spot unnamed.
  struct Claims {
    pattern::SpotId id{-1, -1};
    int sources = 0, direct = 0;
    double strength = 0, area = 0;  // the sources' sums
    double off = 0;                 // the farthest a source's prediction lies, in its steps
    // the row or column neighbour's claim: how far along its step the blob lies (1: where
    // predicted) and how far aside; and the farthest a corner's prediction lies (in steps)
    double along = 0, aside = 0, corner_off = 0;
  };
  struct Proposal {
    Claims first, second;
    bool third = false;  // a third id was claimed
  };
  std::vector<Proposal> proposals(n);
  // Each identified spot's claims (the spot at a predicted place, the id, a row or column
  // neighbour's or a corner's). A source's claims depend only on the ids within one step of it,
  // so they are recomputed only for sources new or next to an id named in the round before
  // (two steps, for margin); the others' are reused: the same ids, a fraction of the rounds'
  // spatial lookups (8 rounds on the ham's frame).
  struct Claim {
    int spot;
    pattern::SpotId id;
    bool direct;
    double off;           // from the prediction, in steps
    double along, aside;  // the blob's offset from the source, in the predicted displacement
  };
  std::vector<std::vector<Claim>> claims;
  std::vector<char> active;
  std::vector<pattern::SpotId> named;
  for (bool grew = true; grew;) {
    grew = false;
    claims.resize(decoded.size());
    active.resize(decoded.size(), 1);
    std::fill(proposals.begin(), proposals.end(), Proposal{});
    for (std::size_t i = 0; i < decoded.size(); ++i) {
      const DecodedSpot& from = decoded[i];
      if (active[i]) claims[i].clear();
      // the source's four axis steps, each looked up once (the diagonals add two of them)
      std::array<int, 4> step_known{0, 0, 0, 0};  // 0: not looked up, 1: known, -1: none
      std::array<std::array<double, 2>, 4> step{};
      const auto axis_step = [&](int sr, int sc) -> const std::array<double, 2>* {
        const int k = sr == 0 ? (sc > 0 ? 0 : 2) : (sr > 0 ? 1 : 3);
        if (step_known[k] == 0)
          step_known[k] = lattice_step(from.row, from.col, sr, sc, step[k][0], step[k][1]) ? 1 : -1;
        return step_known[k] > 0 ? &step[k] : nullptr;
      };
      for (int dr = -1; dr <= 1 && active[i]; ++dr)
        for (int dc = -1; dc <= 1; ++dc) {
          const int r = from.row + dr, c = from.col + dc;
          if ((dr == 0 && dc == 0) || !ids.inside(r, c) || ids.taken(r, c)) continue;
          // where the lattice puts id (r, c): one step along each axis that moves
          double pu = spots[from.spot].u, pv = spots[from.spot].v, step2 = 1e300;
          bool known = true;
          for (const auto& [sr, sc] : {std::pair{dr, 0}, std::pair{0, dc}}) {
            if (sr == 0 && sc == 0) continue;
            const std::array<double, 2>* v = known ? axis_step(sr, sc) : nullptr;
            known = v != nullptr;
            if (!known) break;
            pu += (*v)[0], pv += (*v)[1];
            step2 = std::min(step2, (*v)[0] * (*v)[0] + (*v)[1] * (*v)[1]);
          }
          if (!known) continue;
          int found = -1;
          double best = kGrowSlack * kGrowSlack * step2;
          near->around(pu, pv, 1, [&](int j) {
            const double du = spots[j].u - pu, dv = spots[j].v - pv;
            if (du * du + dv * dv <= best) best = du * du + dv * dv, found = j;
          });
          if (found < 0 || ids.index_of(found) >= 0 || spots[found].truncated || !alike(spots[from.spot], spots[found]) ||
              spots[found].area_px > kGrowLargest * spots[from.spot].area_px)
            continue;
          // a claim the blob cannot carry (another colour, off the id's epipolar line) is no
          // claim: across a depth edge a source's steps reach onto the other surface's spots
          if (!(pattern.at(r, c) == spots[found].colour && check.confirms(found, {r, c}))) continue;
          const double xu = pu - spots[from.spot].u, xv = pv - spots[from.spot].v;
          const double bu = spots[found].u - spots[from.spot].u, bv = spots[found].v - spots[from.spot].v;
          const double x2 = xu * xu + xv * xv;
          claims[i].push_back({found, {r, c}, dr == 0 || dc == 0, std::sqrt(best / step2), (bu * xu + bv * xv) / x2,
                               std::abs(bu * xv - bv * xu) / x2});
        }
      for (const Claim& claim : claims[i]) {
        Proposal& p = proposals[claim.spot];
        Claims* to = p.first.sources == 0 || p.first.id == claim.id     ? &p.first
                     : p.second.sources == 0 || p.second.id == claim.id ? &p.second
                                                                         : nullptr;
        if (!to) {
          p.third = true;
          continue;
        }
        to->id = claim.id;
        ++to->sources;
        to->direct += claim.direct;
        to->off = std::max(to->off, claim.off);
        if (claim.direct)
          to->along = claim.along, to->aside = claim.aside;
        else
          to->corner_off = std::max(to->corner_off, claim.off);
        to->strength += spots[from.spot].strength, to->area += spots[from.spot].area_px;
      }
    }
    named.clear();
    for (std::size_t j = 0; j < n; ++j) {
      Proposal& pr = proposals[j];
      if (pr.second.sources > pr.first.sources) std::swap(pr.first, pr.second);
      if (pr.third || pr.second.sources > 1 || (pr.second.sources == 1 && pr.first.sources < 1 + kGrowMajority))
        continue;
      const Claims& p = pr.first;
      if (p.direct < 1) continue;
      const bool on_line = p.direct == 1 && p.aside <= kGrowOnLineAside && p.along >= kGrowOnLineShortest &&
                           p.along <= kGrowOnLineLongest && p.corner_off <= kGrowSlack;
      const bool one_short = p.sources >= 2 && p.sources + 1 == min_sources && (p.off <= kGrowTightSlack || on_line);
      if (p.sources < min_sources && !one_short) continue;
      if (p.direct == 1 || one_short) {
        const Spot& x = spots[j];
        const double strength = p.strength / p.sources, area = p.area / p.sources;
        if (x.strength < (one_short ? kGrowOneShortDimmest : kGrowDimmest) * strength || x.area_px < kGrowAreaBelow * area ||
            x.area_px > kGrowAreaAbove * area || x.area_px < kGrowSmallestPx || x.strength < kGrowFaintest)
          continue;
      }
      const int r = p.id.row, c = p.id.col;
      // the lattice itself names the blob when three sources, two of them row or column
      // neighbours, all land within kGrowTightSlack of it: then an id beside that the blob could
      // also carry (its colour, on the same epipolar line, a row's neighbour mostly) would need
      // every one of them off by a whole step
      const bool pinned = p.sources >= kGrowPinnedSources && p.direct >= 2 && p.off <= kGrowTightSlack;
      if (ids.taken(r, c) ||
          (!pinned && !only_fitting_id(spots, static_cast<int>(j), p.id, check, pattern,
                                       [&](int rr, int cc) { return ids.taken(rr, cc); })))
        continue;
      decoded.push_back({r, c, spots[j].u, spots[j].v, static_cast<int>(j)});
      ids.add(decoded.back(), static_cast<int>(decoded.size()) - 1);
      named.push_back(p.id);
      grew = true;
    }
    std::fill(active.begin(), active.end(), 0);
    for (const pattern::SpotId& id : named)
      for (int dr = -2; dr <= 2; ++dr)
        for (int dc = -2; dc <= 2; ++dc)
          if (const int x = spot_at(id.row + dr, id.col + dc); x >= 0 && ids.index_of(x) < static_cast<int>(active.size()))
            active[ids.index_of(x)] = 1;
  }
  // the links the lattice found, where both ends had none in that direction
  link_identified_neighbours(decoded, spot_at, graph);
  return decoded;
}

namespace {
// Where a run's candidate may lie from its source, along the source's step: the steps shrink
// towards a silhouette (the surface turns away), so from 0.3 of a step to 1.15 of it, and at
// most 0.3 of a step aside
constexpr double kRunNearest = 0.3, kRunFarthest = 1.15, kRunAside = 0.3;
// how much two neighbouring candidates' offset may differ from their sources' (fraction of
// the sources' step): the run follows the identified line beside it
constexpr double kRunFollow = 0.35;
// consecutive candidates a run needs: each has the colour the pattern has there by chance one
// time in three, so a run of 4 is one in 81 before the epipolar line and the positions
constexpr int kRunLength = 4;
// a line beyond is foreshortened: its spots no larger than their sources (a larger blob there is
// the wash of a surface behind, out of focus), and a run bridges one missing id at most
constexpr double kRunLargest = 1.2;
constexpr int kRunGaps = 1;
}  // namespace

std::vector<DecodedSpot> name_edge_runs(const std::vector<Spot>& spots, AdjacencyGraph& graph,
                                        const EpipolarCheck& check, const pattern::MArray& pattern,
                                        std::vector<DecodedSpot> decoded, std::vector<char>* named_here) {
  const std::size_t n = spots.size();
  if (named_here) named_here->assign(n, 0);
  if (decoded.empty() || n < 2) return decoded;
  IdMap ids(pattern, n, decoded);
  const auto spot_at = [&](int r, int c) { return ids.spot_at(r, c); };
  const std::optional<SpatialGrid> near = lattice_grid(spots, graph);
  if (!near) return decoded;
  // per pattern cell, in direction k: the blob found beyond the identified spot one step back
  const std::size_t cells = static_cast<std::size_t>(pattern.rows) * pattern.cols;
  std::vector<int> claimed_by(n, -1);  // blob -> the cell it was found for (-2: two cells)
  std::vector<DecodedSpot> added;
  for (int k = 0; k < 4; ++k) {
    const int dr = kIdStep[k][0], dc = kIdStep[k][1];
    std::vector<int> candidate(cells, -1);
    for (const DecodedSpot& from : decoded) {
      const int r = from.row + dr, c = from.col + dc;
      if (!ids.inside(r, c) || ids.taken(r, c)) continue;
      const int back = spot_at(from.row - dr, from.col - dc);
      if (back < 0) continue;
      const Spot& s = spots[from.spot];
      const double vu = s.u - spots[back].u, vv = s.v - spots[back].v, step2 = vu * vu + vv * vv;
      if (step2 < 4.0) continue;
      int found = -1;
      double best = 1e300;
      near->around(s.u + 0.7 * vu, s.v + 0.7 * vv, 1, [&](int j) {
        const double du = spots[j].u - s.u, dv = spots[j].v - s.v;
        const double along = (du * vu + dv * vv) / step2, aside = std::abs(du * vv - dv * vu) / step2;
        if (along < kRunNearest || along > kRunFarthest || aside > kRunAside) return;
        const double d2 = du * du + dv * dv;
        if (d2 < best) best = d2, found = j;
      });
      if (found < 0 || ids.index_of(found) >= 0 || spots[found].truncated || spots[found].colour != pattern.at(r, c) ||
          spots[found].strength < kGrowFaintest || spots[found].strength < kAlike * s.strength ||
          spots[found].area_px > kRunLargest * s.area_px || !check.confirms(found, {r, c}))
        continue;
      candidate[static_cast<std::size_t>(r) * pattern.cols + c] = found;
    }
    // runs across k: ids along the line across k, each with a candidate, one missing at most
    // between two, each candidate offset from the one before as their sources are
    const int pr = std::abs(dc);  // the axis across k (0: the runs lie along a row)
    const auto cand = [&](int r, int c) {
      return ids.inside(r, c) ? candidate[static_cast<std::size_t>(r) * pattern.cols + c] : -1;
    };
    const auto follows = [&](const pattern::SpotId& x, const pattern::SpotId& y) {
      const int a = cand(x.row, x.col), b = cand(y.row, y.col);
      const int sa = spot_at(x.row - dr, x.col - dc), sb = spot_at(y.row - dr, y.col - dc);
      if (a < 0 || b < 0 || sa < 0 || sb < 0) return false;
      const double su = spots[sb].u - spots[sa].u, sv = spots[sb].v - spots[sa].v;
      const double eu = spots[b].u - spots[a].u - su, ev = spots[b].v - spots[a].v - sv;
      return eu * eu + ev * ev <= kRunFollow * kRunFollow * (su * su + sv * sv);
    };
    const auto take_run = [&](const std::vector<pattern::SpotId>& run) {
      if (static_cast<int>(run.size()) < kRunLength) return;
      // no other placement of the whole run fits it as well, taken ids or not: in the crowded
      // columns at a silhouette the lattice shears, and at a depth edge the surface behind goes
      // on, so that the next line's spots, one over, can sit where this run's ids are predicted
      // (their colours and epipolar lines then fit the shifted ids, each of them)
      for (int orow = -1; orow <= 1; ++orow)
        for (int ocol = -1; ocol <= 1; ++ocol) {
          if (orow == 0 && ocol == 0) continue;
          std::size_t fit = 0;
          for (const pattern::SpotId& x : run) {
            const int rr = x.row + orow, cc = x.col + ocol, j = cand(x.row, x.col);
            fit += ids.inside(rr, cc) && pattern.at(rr, cc) == spots[j].colour && check.confirms(j, {rr, cc});
          }
          if (fit == run.size()) return;
        }
      for (const pattern::SpotId& x : run) {
        const int j = cand(x.row, x.col);
        const int cell = x.row * pattern.cols + x.col;
        claimed_by[j] = claimed_by[j] == -1 || claimed_by[j] == cell ? cell : -2;
        added.push_back({x.row, x.col, spots[j].u, spots[j].v, j});
      }
    };
    const int lines = pr == 0 ? pattern.rows : pattern.cols, along = pr == 0 ? pattern.cols : pattern.rows;
    std::vector<pattern::SpotId> run;
    for (int line = 0; line < lines; ++line) {
      run.clear();
      int last = -10, gaps = 0;
      for (int i = 0; i < along; ++i) {
        const pattern::SpotId x = pr == 0 ? pattern::SpotId{line, i} : pattern::SpotId{i, line};
        if (cand(x.row, x.col) < 0) continue;
        // a gap is an id no spot has, its source beside the run's
        const pattern::SpotId gap = pr == 0 ? pattern::SpotId{line, i - 1} : pattern::SpotId{i - 1, line};
        const bool bridged = i - last == 1 || (i - last == 2 && gaps < kRunGaps && !ids.taken(gap.row, gap.col) &&
                                               spot_at(gap.row - dr, gap.col - dc) >= 0);
        if (!run.empty() && (!bridged || !follows(run.back(), x))) {
          take_run(run);
          run.clear();
          gaps = 0;
        }
        if (!run.empty() && i - last == 2) ++gaps;
        run.push_back(x);
        last = i;
      }
      take_run(run);
    }
  }
  // a blob two runs claim for two ids, or an id two runs give two blobs, is not named
  std::vector<int> cell_claims(cells, 0);
  for (const DecodedSpot& a : added)
    if (claimed_by[a.spot] >= 0) ++cell_claims[static_cast<std::size_t>(a.row) * pattern.cols + a.col];
  for (const DecodedSpot& a : added) {
    const std::size_t cell = static_cast<std::size_t>(a.row) * pattern.cols + a.col;
    if (claimed_by[a.spot] < 0 || ids.taken(a.row, a.col) || ids.index_of(a.spot) >= 0) continue;
    if (cell_claims[cell] > 1) {
      // the same blob for the same cell from two directions is one claim
      bool same = true;
      for (const DecodedSpot& b : added)
        if (b.row == a.row && b.col == a.col && b.spot != a.spot) same = false;
      if (!same) continue;
    }
    decoded.push_back(a);
    ids.add(a, static_cast<int>(decoded.size()) - 1);
    if (named_here) (*named_here)[a.spot] = 1;
  }
  // their links to the line beside them, where both ends had none
  link_identified_neighbours(decoded, spot_at, graph);
  return decoded;
}

SpotDecoder::SpotDecoder(pattern::WindowTable table, DecoderOptions options)
    : table_(std::move(table)), options_(options) {
  options_.segmentation.colours = table_.array().colours;
  // the distance of the pattern decides how much a window may be repaired
  distance_ = table_.min_hamming();  // a table holds only arrays with the window property
  if (options_.tolerance.by_pattern_distance && distance_ >= 3) {
    options_.tolerance.enabled = true;
    options_.tolerance.max_missing = std::max(options_.tolerance.max_missing, std::min(2, distance_ - 1));
  }
}

DecodeResult SpotDecoder::decode_spots(std::vector<Spot> spots, const EpipolarGeometry* geometry) const {
  DecodeResult r;
  r.detected = std::move(spots);
  // the slivers wait for step 8: the steps before see the spots only
  const auto first_sliver = std::stable_partition(r.detected.begin(), r.detected.end(), [](const Spot& s) { return !s.sliver; });
  std::vector<Spot> slivers(first_sliver, r.detected.end());
  r.detected.erase(first_sliver, r.detected.end());
  AdjacencyGraph graph = build_adjacency(r.detected, options_.mend_links);
  Neighbourhoods hoods = check_graph_consistency(graph);
  int n = static_cast<int>(r.detected.size());
  std::vector<char> edge_run;  // the spots an edge run named (step 8)
  std::optional<EpipolarCheck> epipolar;
  if (geometry) epipolar.emplace(*geometry, r.detected);
  if (options_.mend_links) {
    for (const ShearAxis axis : {ShearAxis::kColumns, ShearAxis::kRows}) {
      graph = resolve_shear(r.detected, graph, hoods, table_, epipolar ? &*epipolar : nullptr, axis);
      hoods = check_graph_consistency(graph);
    }
  }
  if (geometry) {
    const EpipolarOptions& e = options_.epipolar;
    const EpipolarCheck& check = *epipolar;
    ToleranceOptions tolerance = options_.tolerance;
    tolerance.enabled = tolerance.enabled || e.tolerant;
    const std::vector<WindowReading> readings = read_windows(r.detected, hoods, table_, tolerance, &check);
    r.readings = static_cast<int>(readings.size());
    std::vector<IdVote> votes;
    add_window_votes(hoods, readings, votes);
    if (e.segment_length > 0) read_segments(r.detected, graph, check, table_.array(), e.segment_length, votes);
    r.decoded = check_vote_consistency(r.detected, votes, e.min_votes, e.two_exact_votes);
    r.decoded = check_island_consistency(graph, std::move(r.decoded), n, e.min_island, true);
    if (e.propagate) {
      r.decoded = propagate_ids(r.detected, graph, hoods, check, table_.array(), std::move(r.decoded),
                                e.min_sources);
      r.decoded = check_island_consistency(graph, std::move(r.decoded), n, e.min_island, true);
    }
    if (e.grow) {
      r.decoded = grow_lattice(r.detected, graph, check, table_.array(), std::move(r.decoded), e.min_sources);
      r.decoded = check_island_consistency(graph, std::move(r.decoded), n, e.min_island, true);
      if (e.edge_runs) {
        // the slivers join the spots, unlinked
        for (const Spot& x : slivers) {
          r.detected.push_back(x);
          graph.next.push_back({-1, -1, -1, -1});
          Window w{-1, -1, -1, -1, -1, -1, -1, -1, -1};
          w[4] = n++;
          hoods.window.push_back(w);
          epipolar->xy.push_back(geometry->normalise(x.u, x.v));
        }
        r.decoded = name_edge_runs(r.detected, graph, check, table_.array(), std::move(r.decoded), &edge_run);
        r.decoded = check_island_consistency(graph, std::move(r.decoded), n, e.min_island, true);
      }
      // the grown region's new links and sources carry propagation further (once: a second
      // growth named spots whose links then condemned right ones, 1.2 points fewer on the ham)
      if (e.propagate) {
        hoods = check_graph_consistency(graph);
        r.decoded = propagate_ids(r.detected, graph, hoods, check, table_.array(), std::move(r.decoded),
                                  e.min_sources);
        r.decoded = check_island_consistency(graph, std::move(r.decoded), n, e.min_island, true);
      }
    }
  } else {
    const std::vector<WindowReading> readings = read_windows(r.detected, hoods, table_, options_.tolerance);
    r.readings = static_cast<int>(readings.size());
    r.decoded = check_decoding_consistency(r.detected, hoods, readings, options_.min_votes);
    if (options_.min_island > 0)
      r.decoded = check_island_consistency(graph, std::move(r.decoded), n, options_.min_island);
  }
  // a spot cut by the image border helps decode its neighbours, but its centroid is not
  // where its centre is: it is not reported. Nor is a fragment, a blob far smaller than the
  // spots linked to it: a spot cut by a depth edge or the object's silhouette
  std::erase_if(r.decoded, [&](const DecodedSpot& d) {
    return r.detected[d.spot].truncated ||
           (is_fragment(r.detected, graph, d.spot) && !(d.spot < static_cast<int>(edge_run.size()) && edge_run[d.spot]));
  });
  r.graph = std::move(graph);
  r.hoods = std::move(hoods);
  return r;
}

DecodeResult SpotDecoder::decode(const cv::Mat& rgb, const EpipolarGeometry* geometry) const {
  Segmentation seg = segment_spots(rgb, options_.segmentation, &scratch_);
  DecodeResult r = decode_spots(std::move(seg.spots), geometry);
  r.rejected_blobs = seg.rejected;
  return r;
}

}  // namespace vision
