// M-array decoding, step 7: ids given where the identified lattice predicts a spot, links or none (grow_lattice).
#include <algorithm>
#include <cmath>
#include <optional>
#include <tuple>

#include "servo/vision/decoder_support.hpp"
#include "servo/vision/spot_decoder.hpp"

namespace vision {
using namespace decoder_support;



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
          if (!(pattern.at(r, c) == spots[found].colour && check.confirms_grown(found, {r, c}))) continue;
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

}  // namespace vision
