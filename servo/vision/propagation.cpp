// M-array decoding, step 6: ids spread to linked neighbours whose colour and epipolar line agree (propagate_ids).
#include <algorithm>
#include <cmath>
#include <optional>
#include <tuple>

#include "servo/vision/decoder_support.hpp"
#include "servo/vision/spot_decoder.hpp"

namespace vision {
using namespace decoder_support;



namespace {

// In rounds: an undecoded spot takes an id when at least `min_sources` decoded spots around
// it (one of them linked) propose the same id (and none proposes another).
struct Proposal {
  pattern::SpotId id{-1, -1};
  int sources = 0;
  bool conflict = false;
};

class Propagation {
 public:
  Propagation(const std::vector<Spot>& spots, const AdjacencyGraph& graph, const Neighbourhoods& hoods,
              const EpipolarCheck& check, const pattern::MArray& pattern, std::vector<DecodedSpot>& decoded,
              double slack, double alike)
      : spots_(spots), graph_(graph), hoods_(hoods), check_(check), pattern_(pattern), decoded_(decoded),
        ids_(pattern, spots.size(), decoded), proposals_(spots.size()), slack_(slack), alike_(alike) {}

  // one round; false when it named nobody
  bool round(int min_sources) {
    std::fill(proposals_.begin(), proposals_.end(), Proposal{});
    for (const DecodedSpot& from : decoded_)
      for (int k = 0; k < 4; ++k) propose_linked(from, k);
    second_by_corners();
    bool grew = false;
    for (std::size_t j = 0; j < spots_.size(); ++j) {
      const Proposal& p = proposals_[j];
      if (p.conflict || p.sources < min_sources) continue;
      const int r = p.id.row, c = p.id.col;
      if (!ids_.inside(r, c) || ids_.taken(r, c)) continue;
      if (!only_fitting_id(spots_, static_cast<int>(j), p.id, check_, pattern_,
                           [&](int rr, int cc) { return ids_.taken(rr, cc); }))
        continue;
      decoded_.push_back({r, c, spots_[j].u, spots_[j].v, static_cast<int>(j), NamedBy::kPropagation});
      ids_.add(decoded_.back(), static_cast<int>(decoded_.size()) - 1);
      grew = true;
    }
    return grew;
  }

 private:
  // the spot linked to `from` in direction k proposes the id one step on, if it continues the
  // source's lattice, looks like its spots, and what lies beyond it agrees
  void propose_linked(const DecodedSpot& from, int k) {
    const int j = graph_.next[from.spot][k];
    if (j < 0 || ids_.index_of(j) >= 0 || spots_[j].truncated) return;
    const pattern::SpotId id{from.row + kIdStep[k][0], from.col + kIdStep[k][1]};
    Proposal& p = proposals_[j];
    if (!continues_lattice(from, j, k)) return;  // j is not where this source's lattice goes
    // j looks like a spot of the source's surface: a faint speck of noise, or the dim light
    // of a surface behind an edge (defocused, oblique), is not
    if (!alike(spots_[from.spot], spots_[j], alike_)) return;
    if (!beyond_agrees(from, j, k, id)) return;
    if (p.sources > 0 && !(p.id == id)) p.conflict = true;
    p.id = id;
    ++p.sources;
  }
  // decoded diagonal neighbours (corners that both paths round agree on) second a proposal:
  // a spot beyond a decoded edge has its one linked source and two corners
  void second_by_corners() {
    for (std::size_t j = 0; j < spots_.size(); ++j) {
      Proposal& p = proposals_[j];
      if (p.sources == 0 || p.conflict) continue;
      for (const int i : {0, 2, 6, 8}) {
        const int q = hoods_.window[j][i];
        if (q < 0 || ids_.index_of(q) < 0) continue;
        const DecodedSpot& d = decoded_[ids_.index_of(q)];
        const pattern::SpotId id{d.row - (i / 3 - 1), d.col - (i % 3 - 1)};
        if (!(p.id == id)) p.conflict = true;
        ++p.sources;
      }
    }
  }
  bool continues_lattice(const DecodedSpot& from, int j, int k) const {
    const int dr = kIdStep[k][0], dc = kIdStep[k][1];
    const auto at = [&](int r, int c) { return ids_.spot_at(r, c); };
    // reference steps in k: behind the source, then beside it (either side)
    const std::array<std::pair<int, int>, 3> refs{{{at(from.row - dr, from.col - dc), from.spot},
                                                  {at(from.row + dc, from.col + dr), at(from.row + dc + dr, from.col + dr + dc)},
                                                  {at(from.row - dc, from.col - dr), at(from.row - dc + dr, from.col - dr + dc)}}};
    for (const auto& [a, b] : refs) {
      if (a < 0 || b < 0) continue;
      const double vu = spots_[b].u - spots_[a].u, vv = spots_[b].v - spots_[a].v;
      const double eu = spots_[j].u - spots_[from.spot].u - vu, ev = spots_[j].v - spots_[from.spot].v - vv;
      return eu * eu + ev * ev <= slack_ * slack_ * (vu * vu + vv * vv);
    }
    return false;  // nothing to compare with: not propagated
  }
  // The spot linked beyond j, if any, must go on with the lattice and the pattern: at an
  // object's edge, the spot that sits where the lattice goes on belongs to the surface behind,
  // and the one beyond it follows that surface's spacing, not this one's.
  bool beyond_agrees(const DecodedSpot& from, int j, int k, const pattern::SpotId& id) const {
    const int b = graph_.next[j][k];
    if (b < 0) return true;
    const pattern::SpotId next{id.row + kIdStep[k][0], id.col + kIdStep[k][1]};
    if (ids_.index_of(b) >= 0)
      return decoded_[ids_.index_of(b)].row == next.row && decoded_[ids_.index_of(b)].col == next.col;
    if (next.row < 0 || next.col < 0 || next.row >= pattern_.rows || next.col >= pattern_.cols) return false;
    if (pattern_.at(next.row, next.col) != spots_[b].colour) return false;
    const double vu = spots_[j].u - spots_[from.spot].u, vv = spots_[j].v - spots_[from.spot].v;
    const double eu = spots_[b].u - spots_[j].u - vu, ev = spots_[b].v - spots_[j].v - vv;
    return eu * eu + ev * ev <= slack_ * slack_ * (vu * vu + vv * vv);
  }

  const std::vector<Spot>& spots_;
  const AdjacencyGraph& graph_;
  const Neighbourhoods& hoods_;
  const EpipolarCheck& check_;
  const pattern::MArray& pattern_;
  std::vector<DecodedSpot>& decoded_;
  IdMap ids_;
  std::vector<Proposal> proposals_;
  double slack_, alike_;  // EpipolarOptions::propagate_slack, GrowthOptions::alike
};

}  // namespace

std::vector<DecodedSpot> propagate_ids(const std::vector<Spot>& spots, const AdjacencyGraph& graph,
                                       const Neighbourhoods& hoods, const EpipolarCheck& check,
                                       const pattern::MArray& pattern, std::vector<DecodedSpot> decoded,
                                       int min_sources, double slack, double alike) {
  Propagation propagation(spots, graph, hoods, check, pattern, decoded, slack, alike);
  while (propagation.round(min_sources)) {
  }
  return decoded;
}

}  // namespace vision
