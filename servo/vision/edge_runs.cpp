// M-array decoding, step 7: the foreshortened line beyond an identified one, named as a run (name_edge_runs).
#include <algorithm>
#include <cmath>
#include <optional>
#include <tuple>

#include "servo/vision/decoder_support.hpp"
#include "servo/vision/spot_decoder.hpp"

namespace vision {
using namespace decoder_support;


namespace {

// The runs beyond the identified lines in one direction k: per pattern cell, the blob found
// beyond the identified spot one step back, then the lines of such cells read as runs.
class EdgeRuns {
 public:
  EdgeRuns(const std::vector<Spot>& spots, const EpipolarCheck& check, const pattern::MArray& pattern, const IdMap& ids,
           const SpatialGrid& near, int k, const EdgeRunOptions& options, const GrowthOptions& growth, double cell_slack)
      : spots_(spots), check_(check), pattern_(pattern), ids_(ids), near_(near), dr_(kIdStep[k][0]), dc_(kIdStep[k][1]),
        candidate_(static_cast<std::size_t>(pattern.rows) * pattern.cols, -1), o_(options), faintest_(growth.faintest),
        alike_(growth.alike), farthest_(growth.on_line_stretch), cell_slack_(cell_slack) {}

  // each cell's candidate: the blob ahead of an identified spot along its step
  void find_candidates(const std::vector<DecodedSpot>& decoded) {
    const double middle = (o_.nearest + farthest_) / 2;  // where a candidate is looked for
    for (const DecodedSpot& from : decoded) {
      const int r = from.row + dr_, c = from.col + dc_;
      if (!ids_.inside(r, c) || ids_.taken(r, c)) continue;
      const int back = ids_.spot_at(from.row - dr_, from.col - dc_);
      if (back < 0) continue;
      const Spot& s = spots_[from.spot];
      const double vu = s.u - spots_[back].u, vv = s.v - spots_[back].v, step2 = vu * vu + vv * vv;
      if (step2 <= 0) continue;  // two blobs at one place: no step
      int found = -1;
      double best = 1e300;
      near_.around(s.u + middle * vu, s.v + middle * vv, 1, [&](int j) {
        const double du = spots_[j].u - s.u, dv = spots_[j].v - s.v;
        const double along = (du * vu + dv * vv) / step2, aside = std::abs(du * vv - dv * vu) / step2;
        if (along < o_.nearest || along > farthest_ || aside > o_.aside) return;
        const double d2 = du * du + dv * dv;
        if (d2 < best) best = d2, found = j;
      });
      if (found < 0 || ids_.index_of(found) >= 0 || spots_[found].truncated || spots_[found].colour != pattern_.at(r, c) ||
          spots_[found].strength < faintest_ || spots_[found].strength < alike_ * s.strength ||
          spots_[found].area_px > o_.largest * s.area_px || !check_.confirms_grown(found, {r, c}))
        continue;
      candidate_[static_cast<std::size_t>(r) * pattern_.cols + c] = found;
    }
  }

  // runs across k: ids along the line across k, each with a candidate, one missing at most
  // between two, each candidate offset from the one before as their sources are
  void read_runs(std::vector<int>& claimed_by, std::vector<DecodedSpot>& added) const {
    const int pr = std::abs(dc_);  // the axis across k (0: the runs lie along a row)
    const int lines = pr == 0 ? pattern_.rows : pattern_.cols, along = pr == 0 ? pattern_.cols : pattern_.rows;
    std::vector<pattern::SpotId> run;
    for (int line = 0; line < lines; ++line) {
      run.clear();
      int last = -10, gaps = 0;
      for (int i = 0; i < along; ++i) {
        const pattern::SpotId x = pr == 0 ? pattern::SpotId{line, i} : pattern::SpotId{i, line};
        if (cand(x.row, x.col) < 0) continue;
        // a gap is an id no spot has, its source beside the run's
        const pattern::SpotId gap = pr == 0 ? pattern::SpotId{line, i - 1} : pattern::SpotId{i - 1, line};
        const bool bridged = i - last == 1 || (i - last == 2 && gaps < o_.gaps && !ids_.taken(gap.row, gap.col) &&
                                               ids_.spot_at(gap.row - dr_, gap.col - dc_) >= 0);
        if (!run.empty() && (!bridged || !follows(run.back(), x))) {
          take_run(run, claimed_by, added);
          run.clear();
          gaps = 0;
        }
        if (!run.empty() && i - last == 2) ++gaps;
        run.push_back(x);
        last = i;
      }
      take_run(run, claimed_by, added);
    }
  }

 private:
  int cand(int r, int c) const {
    return ids_.inside(r, c) ? candidate_[static_cast<std::size_t>(r) * pattern_.cols + c] : -1;
  }
  // two neighbouring candidates and their sources form a lattice cell: the candidates' offset
  // differs from their sources' by at most CellShape::cell_slack of the sources' step (the run
  // follows the identified line beside it)
  bool follows(const pattern::SpotId& x, const pattern::SpotId& y) const {
    const int a = cand(x.row, x.col), b = cand(y.row, y.col);
    const int sa = ids_.spot_at(x.row - dr_, x.col - dc_), sb = ids_.spot_at(y.row - dr_, y.col - dc_);
    if (a < 0 || b < 0 || sa < 0 || sb < 0) return false;
    const double su = spots_[sb].u - spots_[sa].u, sv = spots_[sb].v - spots_[sa].v;
    const double eu = spots_[b].u - spots_[a].u - su, ev = spots_[b].v - spots_[a].v - sv;
    return eu * eu + ev * ev <= cell_slack_ * cell_slack_ * (su * su + sv * sv);
  }
  void take_run(const std::vector<pattern::SpotId>& run, std::vector<int>& claimed_by,
                std::vector<DecodedSpot>& added) const {
    if (static_cast<int>(run.size()) < o_.length) return;
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
          fit += ids_.inside(rr, cc) && pattern_.at(rr, cc) == spots_[j].colour && check_.confirms(j, {rr, cc});
        }
        if (fit == run.size()) return;
      }
    for (const pattern::SpotId& x : run) {
      const int j = cand(x.row, x.col);
      const int cell = x.row * pattern_.cols + x.col;
      claimed_by[j] = claimed_by[j] == -1 || claimed_by[j] == cell ? cell : -2;
      added.push_back({x.row, x.col, spots_[j].u, spots_[j].v, j, NamedBy::kEdgeRun});
    }
  }

  const std::vector<Spot>& spots_;
  const EpipolarCheck& check_;
  const pattern::MArray& pattern_;
  const IdMap& ids_;
  const SpatialGrid& near_;
  int dr_, dc_;
  std::vector<int> candidate_;
  const EdgeRunOptions& o_;
  float faintest_;     // GrowthOptions::faintest: a run's blob is no fainter than a grown spot
  double alike_;       // GrowthOptions::alike
  double farthest_;    // GrowthOptions::on_line_stretch: the farthest a candidate lies along the step
  double cell_slack_;  // CellShape::cell_slack: two neighbours and their sources form a lattice cell
};

}  // namespace

std::vector<DecodedSpot> name_edge_runs(const std::vector<Spot>& spots, AdjacencyGraph& graph,
                                        const EpipolarCheck& check, const pattern::MArray& pattern,
                                        std::vector<DecodedSpot> decoded, std::vector<char>* named_here,
                                        const EdgeRunOptions& options, const GrowthOptions& growth,
                                        const CellShape& shape) {
  const std::size_t n = spots.size();
  if (named_here) named_here->assign(n, 0);
  if (decoded.empty() || n < 2) return decoded;
  IdMap ids(pattern, n, decoded);
  const std::optional<SpatialGrid> near = lattice_grid(spots, graph);
  if (!near) return decoded;
  std::vector<int> claimed_by(n, -1);  // blob -> the cell it was found for (-2: two cells)
  std::vector<DecodedSpot> added;
  for (int k = 0; k < 4; ++k) {
    EdgeRuns runs(spots, check, pattern, ids, *near, k, options, growth, shape.cell_slack);
    runs.find_candidates(decoded);
    runs.read_runs(claimed_by, added);
  }
  // a blob two runs claim for two ids, or an id two runs give two blobs, is not named
  const std::size_t cells = static_cast<std::size_t>(pattern.rows) * pattern.cols;
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
  link_identified_neighbours(decoded, [&](int r, int c) { return ids.spot_at(r, c); }, graph);
  return decoded;
}

}  // namespace vision
