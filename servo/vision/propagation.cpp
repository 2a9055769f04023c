// M-array decoding, step 6: ids spread to linked neighbours whose colour and epipolar line agree (propagate_ids).
#include <algorithm>
#include <cmath>
#include <optional>
#include <tuple>

#include "servo/vision/decoder_support.hpp"
#include "servo/vision/spot_decoder.hpp"

namespace vision {
using namespace decoder_support;



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

}  // namespace vision
