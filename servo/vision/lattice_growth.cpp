// M-array decoding, step 6: ids given where the identified lattice predicts a spot, links or none (grow_lattice).
#include <algorithm>
#include <cmath>
#include <optional>
#include <tuple>

#include "servo/vision/decoder_support.hpp"
#include "servo/vision/spot_decoder.hpp"

namespace vision {
using namespace decoder_support;



namespace {

// The claims on one spot: the id most sources name, and the one other id (if any) that some
// source names instead. On a curved surface one source's step can be a little off and place
// its neighbour's id on the spot; one such dissent is outvoted by the sources a claim needs
// anyway (`min_sources`, or two on a tight prediction), a second dissenting source or a third id
// leaves the spot unnamed. (Outvoted only by two sources more than the claim had, the rule named
// 26 ids fewer of 5.6 million on the calibrated tuning sweeps, the same wrong ids.)
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
// One identified spot's claim: the spot at a predicted place, the id, a row or column
// neighbour's or a corner's.
struct Claim {
  int spot;
  pattern::SpotId id;
  bool direct;
  double off;           // from the prediction, in steps
  double along, aside;  // the blob's offset from the source, in the predicted displacement
};

// The identified lattice and what it predicts: the steps between identified spots, the blob
// where each id around a source should be, and whether a blob may take the id most claim.
class Lattice {
 public:
  Lattice(const std::vector<Spot>& spots, const EpipolarCheck& check, const pattern::MArray& pattern, const IdMap& ids,
          const SpatialGrid& near, const GrowthOptions& options, std::vector<GrowthOutcome>* outcomes)
      : spots_(spots), check_(check), pattern_(pattern), ids_(ids), near_(near), o_(options), outcomes_(outcomes),
        by_colour_(ids_by_colour(pattern)) {}

  // The lattice step (dr, dc) at the identified spot (r, c), from identified spots only: ahead
  // of it, behind it, or beside it (the next row or column), the nearest first.
  bool step(int r, int c, int dr, int dc, double& vu, double& vv) const {
    const auto at = [&](int rr, int cc) { return ids_.spot_at(rr, cc); };
    const std::array<std::pair<int, int>, 4> refs{{{at(r, c), at(r + dr, c + dc)},
                                                  {at(r - dr, c - dc), at(r, c)},
                                                  {at(r + dc, c + dr), at(r + dc + dr, c + dr + dc)},
                                                  {at(r - dc, c - dr), at(r - dc + dr, c - dr + dc)}}};
    for (const auto& [a, b] : refs)
      if (a >= 0 && b >= 0) {
        vu = spots_[b].u - spots_[a].u, vv = spots_[b].v - spots_[a].v;
        return true;
      }
    return false;
  }

  // The source's claims on the free ids around it: where the lattice puts each (one step along
  // each axis that moves), the blob there, if it can carry the id.
  void claims_of(const DecodedSpot& from, std::vector<Claim>& out) const {
    // the source's four axis steps, each looked up once (the diagonals add two of them)
    std::array<int, 4> known_step{0, 0, 0, 0};  // 0: not looked up, 1: known, -1: none
    std::array<std::array<double, 2>, 4> steps{};
    const auto axis_step = [&](int sr, int sc) -> const std::array<double, 2>* {
      const int k = sr == 0 ? (sc > 0 ? 0 : 2) : (sr > 0 ? 1 : 3);
      if (known_step[k] == 0) known_step[k] = step(from.row, from.col, sr, sc, steps[k][0], steps[k][1]) ? 1 : -1;
      return known_step[k] > 0 ? &steps[k] : nullptr;
    };
    for (int dr = -1; dr <= 1; ++dr)
      for (int dc = -1; dc <= 1; ++dc) {
        const int r = from.row + dr, c = from.col + dc;
        if ((dr == 0 && dc == 0) || !ids_.inside(r, c) || ids_.taken(r, c)) continue;
        double pu = spots_[from.spot].u, pv = spots_[from.spot].v, step2 = 1e300;
        bool known = true;
        for (const auto& [sr, sc] : {std::pair{dr, 0}, std::pair{0, dc}}) {
          if (sr == 0 && sc == 0) continue;
          const std::array<double, 2>* v = known ? axis_step(sr, sc) : nullptr;
          known = v != nullptr;
          if (!known) break;
          pu += (*v)[0], pv += (*v)[1];
          step2 = std::min(step2, (*v)[0] * (*v)[0] + (*v)[1] * (*v)[1]);
        }
        if (known) claim_at(from, {r, c}, dr == 0 || dc == 0, pu, pv, step2, out);
      }
  }

  // Whether blob j takes the id most sources claim (kNamed), or why not.
  GrowthOutcome judge(std::size_t j, const Proposal& pr, int min_sources) const {
    using G = GrowthOutcome;
    if (pr.third || pr.second.sources > 1) return G::kDissent;
    const Claims& p = pr.first;
    if (p.direct < 1) return G::kNoDirectSource;
    const bool on_line = p.direct == 1 && p.aside <= o_.tight_slack && p.along * o_.on_line_stretch >= 1 &&
                         p.along <= o_.on_line_stretch && p.corner_off <= o_.slack;
    const bool one_short = p.sources >= 2 && p.sources + 1 == min_sources && (p.off <= o_.tight_slack || on_line);
    if (p.sources < min_sources && !one_short) return G::kFewSources;
    if ((p.direct == 1 || one_short) && !looks_like_sources(spots_[j], p)) return G::kUnlikeSources;
    // the lattice itself names the blob (pins it) when as many sources as asked, two of them
    // row or column neighbours, all land within o_.tight_slack of it: then an id beside that the
    // blob could also carry (its colour, on the same epipolar line, a row's neighbour mostly)
    // would need every one of them off by a whole step, so no uniqueness among the ids around it
    // is asked. Along a row the epipolar lines coincide, and a row's neighbour of the same colour
    // fits as well as the id itself one time in three: such spots were refused however many
    // sources agreed (the table at the pattern's corner, the ham's flanks). Ham 89.7 -> 90.3 % of
    // its readable spots, the same wrong ids in 32 calibrated sweeps of 1000 poses. (A number of
    // its own, 3, is step 6's min_sources: no number.)
    const bool pinned = p.sources >= min_sources && p.direct >= 2 && p.off <= o_.tight_slack;
    const auto taken = [&](int rr, int cc) { return ids_.taken(rr, cc); };
    const int b = static_cast<int>(j);
    if (ids_.taken(p.id.row, p.id.col)) return G::kTaken;
    // (only_fitting_id holds the blob to the grown limit too: which of the two refused it is
    // asked only when one did)
    if (pinned ? !check_.confirms_grown(b, p.id) : !only_fitting_id(spots_, b, p.id, check_, pattern_, taken))
      return check_.confirms_grown(b, p.id) ? G::kNeighbourFits : G::kResidual;
    if (!nearest_free_line(b, p.id, check_, pattern_, of_colour(spots_[j].colour), taken)) return G::kNearerLine;
    return G::kNamed;
  }

  // Whether another blob of `free` (the blobs of each colour without an id once the lattice has
  // grown) could be the spot of the id x given to blob j: on x's line within the grown limit and
  // as bright as a grown blob may be against its source (`alike`; nearest_free_blob). Asked when
  // growth has ended, not while it grows: while the lattice is still to reach a region, the free
  // ids of a projector's epipolar line show their spots on x's camera line, each where its own id
  // lies, and asked of every claim the test stopped the plane's lattice growing from an island
  // (36 spots, where it grows to over 300 without it). Strength, not area: the spot behind a silhouette whose id the lattice
  // gave is small (0.09-0.39 of the blob's area on the dark ham's wall) but not faint (0.48-0.69
  // of its strength); a wash that is no spot is faint (0.1-0.25).
  bool has_rival(std::size_t j, const pattern::SpotId& x, const std::vector<std::vector<int>>& free) const {
    const int colour = pattern_.at(x.row, x.col);
    if (colour < 0 || colour >= static_cast<int>(free.size())) return false;
    const auto rival = [&](int i) { return spots_[static_cast<std::size_t>(i)].strength >= o_.alike * spots_[j].strength; };
    return !nearest_free_blob(static_cast<int>(j), x, check_, pattern_, free[static_cast<std::size_t>(colour)], rival);
  }

 private:
  // the blob nearest the predicted place (within o_.slack of a step), if it may carry the id
  void claim_at(const DecodedSpot& from, const pattern::SpotId& id, bool direct, double pu, double pv, double step2,
                std::vector<Claim>& out) const {
    int found = -1;
    double best = o_.slack * o_.slack * step2;
    near_.around(pu, pv, 1, [&](int j) {
      const double du = spots_[j].u - pu, dv = spots_[j].v - pv;
      if (du * du + dv * dv <= best) best = du * du + dv * dv, found = j;
    });
    const Spot& source = spots_[from.spot];
    if (found < 0 || ids_.index_of(found) >= 0) return;
    // a claim the blob cannot carry (another colour, off the id's epipolar line) is no claim:
    // across a depth edge a source's steps reach onto the other surface's spots. One it could
    // carry (within the tolerance) counts, as a vote or as a dissent; only the id named must lie
    // within the frame's grown limit (judge). Gated at the limit, a dissent the tolerance allows
    // went unheard: on 72 tuning sweeps of 1000 poses the dark ham's wrong ids from 4 to 1, the
    // same ids elsewhere but 0.1 points fewer in 4 sweeps.
    if (spots_[found].truncated || !alike(source, spots_[found], o_.alike) ||
        spots_[found].area_px > source.area_px / o_.alike ||
        !(pattern_.at(id.row, id.col) == spots_[found].colour && check_.confirms(found, id))) {
      if (outcomes_ && (*outcomes_)[found] == GrowthOutcome::kUnclaimed) (*outcomes_)[found] = GrowthOutcome::kUnlikeClaim;
      return;
    }
    const double xu = pu - source.u, xv = pv - source.v;
    const double bu = spots_[found].u - source.u, bv = spots_[found].v - source.v;
    const double x2 = xu * xu + xv * xv;
    out.push_back({found, id, direct, std::sqrt(best / step2), (bu * xu + bv * xv) / x2, std::abs(bu * xv - bv * xu) / x2});
  }
  // a spot named from a single row or column neighbour, or one source short, looks like its sources' mean
  bool looks_like_sources(const Spot& x, const Claims& p) const {
    const double strength = p.strength / p.sources, area = p.area / p.sources;
    return x.strength >= o_.unlike * strength && x.area_px >= o_.unlike * area &&
           x.area_px * o_.unlike <= area && x.strength >= o_.faintest;
  }

  const std::vector<Spot>& spots_;
  const EpipolarCheck& check_;
  const pattern::MArray& pattern_;
  const IdMap& ids_;
  const SpatialGrid& near_;
  const GrowthOptions& o_;
  std::vector<GrowthOutcome>* const outcomes_;  // where a refused claim is noted (optional)
  const std::vector<std::vector<int>> by_colour_;  // the pattern's ids of each colour
  const std::vector<int> none_;
  const std::vector<int>& of_colour(int colour) const {
    return colour >= 0 && colour < static_cast<int>(by_colour_.size()) ? by_colour_[colour] : none_;
  }
};

// A source's claim into the proposals on its blob.
void tally(const Claim& claim, const Spot& source, std::vector<Proposal>& proposals) {
  Proposal& p = proposals[claim.spot];
  Claims* to = p.first.sources == 0 || p.first.id == claim.id     ? &p.first
               : p.second.sources == 0 || p.second.id == claim.id ? &p.second
                                                                   : nullptr;
  if (!to) {
    p.third = true;
    return;
  }
  to->id = claim.id;
  ++to->sources;
  to->direct += claim.direct;
  to->off = std::max(to->off, claim.off);
  if (claim.direct)
    to->along = claim.along, to->aside = claim.aside;
  else
    to->corner_off = std::max(to->corner_off, claim.off);
  to->strength += source.strength, to->area += source.area_px;
}

// The grown spots (from `first_grown` on) whose id another free blob could be the spot of
// (Lattice::has_rival), withdrawn once growth has ended.
std::vector<DecodedSpot> withdraw_rivalled(std::vector<DecodedSpot> decoded, std::size_t first_grown, const Lattice& lattice,
                                           const IdMap& ids, const std::vector<Spot>& spots, int colours,
                                           std::vector<GrowthOutcome>* outcomes) {
  std::vector<std::vector<int>> free(static_cast<std::size_t>(std::max(0, colours)));
  for (std::size_t i = 0; i < spots.size(); ++i)
    if (const int c = spots[i].colour; c >= 0 && c < colours && ids.index_of(static_cast<int>(i)) < 0)
      free[static_cast<std::size_t>(c)].push_back(static_cast<int>(i));
  std::vector<DecodedSpot> kept;
  kept.reserve(decoded.size());
  for (std::size_t k = 0; k < decoded.size(); ++k) {
    const DecodedSpot& d = decoded[k];
    if (k >= first_grown && lattice.has_rival(static_cast<std::size_t>(d.spot), {d.row, d.col}, free)) {
      if (outcomes) (*outcomes)[static_cast<std::size_t>(d.spot)] = GrowthOutcome::kNearerBlob;
      continue;
    }
    kept.push_back(d);
  }
  return kept;
}
}  // namespace

std::vector<DecodedSpot> grow_lattice(const std::vector<Spot>& spots, AdjacencyGraph& graph,
                                      const EpipolarCheck& check, const pattern::MArray& pattern,
                                      std::vector<DecodedSpot> decoded, int min_sources, const GrowthOptions& options,
                                      std::vector<GrowthOutcome>* outcomes) {
  const std::size_t n = spots.size();
  if (outcomes) {
    outcomes->assign(n, GrowthOutcome::kUnclaimed);
    for (const DecodedSpot& d : decoded) (*outcomes)[d.spot] = GrowthOutcome::kNamed;
  }
  if (decoded.empty() || n < 2) return decoded;
  const std::size_t first_grown = decoded.size();
  IdMap ids(pattern, n, decoded);
  const std::optional<SpatialGrid> near = lattice_grid(spots, graph);
  if (!near) return decoded;
  const Lattice lattice(spots, check, pattern, ids, *near, options, outcomes);
  std::vector<Proposal> proposals(n);
  // the blobs some claim landed on this round, judged in index order, as a pass over every
  // blob would: the proposals cleared and judged are those, not the frame's every blob
  std::vector<int> touched;
  // A source's claims depend only on the ids within one step of it, so they are recomputed
  // only for sources new or next to an id named in the round before (two steps, for margin);
  // the others' are reused: the same ids, a fraction of the rounds' spatial lookups (8 rounds
  // on the ham's frame).
  std::vector<std::vector<Claim>> claims;
  std::vector<char> active;
  std::vector<pattern::SpotId> named;
  for (bool grew = true; grew;) {
    grew = false;
    claims.resize(decoded.size());
    active.resize(decoded.size(), 1);
    for (const int j : touched) proposals[j] = Proposal{};
    touched.clear();
    for (std::size_t i = 0; i < decoded.size(); ++i) {
      if (active[i]) {
        claims[i].clear();
        lattice.claims_of(decoded[i], claims[i]);
      }
      for (const Claim& claim : claims[i]) {
        if (proposals[claim.spot].first.sources == 0) touched.push_back(claim.spot);  // its first claim
        tally(claim, spots[decoded[i].spot], proposals);
      }
    }
    std::sort(touched.begin(), touched.end());
    named.clear();
    for (const int blob : touched) {
      const std::size_t j = static_cast<std::size_t>(blob);
      Proposal& pr = proposals[j];
      if (pr.second.sources > pr.first.sources) std::swap(pr.first, pr.second);
      if (pr.first.sources == 0) continue;
      const GrowthOutcome outcome = lattice.judge(j, pr, min_sources);
      if (outcomes) (*outcomes)[j] = outcome;
      if (outcome != GrowthOutcome::kNamed) continue;
      decoded.push_back({pr.first.id.row, pr.first.id.col, spots[j].u, spots[j].v, static_cast<int>(j), NamedBy::kLattice});
      // a part of a footprint cut by an edge, smaller than the spots that predict it: named, but
      // no feature of the law (DecodedSpot::clipped)
      decoded.back().clipped = spots[j].area_px < options.unlike * pr.first.area / pr.first.sources;
      ids.add(decoded.back(), static_cast<int>(decoded.size()) - 1);
      named.push_back(pr.first.id);
      grew = true;
    }
    std::fill(active.begin(), active.end(), 0);
    for (const pattern::SpotId& id : named)
      for (int dr = -2; dr <= 2; ++dr)
        for (int dc = -2; dc <= 2; ++dc)
          if (const int x = ids.spot_at(id.row + dr, id.col + dc); x >= 0 && ids.index_of(x) < static_cast<int>(active.size()))
            active[ids.index_of(x)] = 1;
  }
  const std::size_t grown = decoded.size();
  decoded = withdraw_rivalled(std::move(decoded), first_grown, lattice, ids, spots, pattern.colours, outcomes);
  // the links the lattice found, where both ends had none in that direction (the ids' owners
  // looked up again only where a grown spot was withdrawn: most frames withdraw none)
  const std::optional<IdMap> after = decoded.size() == grown ? std::nullopt : std::optional<IdMap>(IdMap(pattern, n, decoded));
  const IdMap& owners = after ? *after : ids;
  link_identified_neighbours(decoded, [&](int r, int c) { return owners.spot_at(r, c); }, graph);
  return decoded;
}

}  // namespace vision
