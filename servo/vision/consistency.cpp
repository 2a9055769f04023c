// M-array decoding, steps 4 and 5: the votes a spot gets must agree (check_vote_consistency,
// check_decoding_consistency), and linked decoded spots carry ids one step apart (check_island_consistency).
#include <algorithm>
#include <cmath>
#include <optional>
#include <tuple>

#include "servo/vision/decoder_support.hpp"
#include "servo/vision/spot_decoder.hpp"

namespace vision {
using namespace decoder_support;

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
                                                    const std::vector<WindowReading>& readings, int min_votes,
                                                    const LineContext* lines) {
  std::vector<IdVote> votes;
  votes.reserve(readings.size() * 9);
  add_window_votes(hoods, readings, votes, lines);
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
                                                  int spot_count, int min_island, bool sheared_links,
                                                  bool within_region) {
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
  // it disagree. Where only one end's region is that large, only the other end is condemned:
  // the large region's spot is not what the link makes doubtful (the egg's silhouette row
  // linked to a patch of the table: +0.1-0.3 points of the egg's readable spots, no wrong id
  // added in 204 tuning sweeps of 1000 poses). `within_region`: a link whose ends lie in one
  // large region is what is wrong too (restore_window_spots says when).
  const Islands regions = find_islands(graph, decoded, at, all, [&](int i, int j, int k) {
    return agrees(decoded[i], decoded[j], k);
  });
  const auto large = [&](int i) { return regions.size[regions.of[i]] >= min_island; };
  std::vector<char> keep(decoded.size(), 1);
  for (std::size_t i = 0; i < decoded.size(); ++i)
    for (int k = 0; k < 4; ++k) {
      const int j = graph.next[decoded[i].spot][k];
      if (j < 0 || at[j] < 0 || agrees(decoded[i], decoded[at[j]], k)) continue;
      const bool large_i = min_island > 0 && large(static_cast<int>(i)), large_j = min_island > 0 && large(at[j]);
      if (large_i && large_j && (regions.of[i] != regions.of[at[j]] || within_region)) continue;
      if (!large_i || large_j) keep[i] = 0;  // a spot is kept only when its region alone is large
      if (!large_j || large_i) keep[at[j]] = 0;
    }
  // islands of id-consistent linked spots
  const Islands islands = find_islands(graph, decoded, at, [&](int i) { return keep[i] != 0; },
                                       [](int, int, int) { return true; });
  std::vector<DecodedSpot> out;
  for (std::size_t i = 0; i < decoded.size(); ++i)
    if (keep[i] && islands.size[islands.of[i]] >= min_island) out.push_back(decoded[i]);
  return out;
}

std::vector<DecodedSpot> restore_window_spots(const AdjacencyGraph& graph, const std::vector<DecodedSpot>& voted,
                                              std::vector<DecodedSpot> decoded, int spot_count, int min_island,
                                              const pattern::MArray& pattern) {
  IdMap ids(pattern, static_cast<std::size_t>(spot_count), decoded);
  bool added = false;
  for (const DecodedSpot& d : check_island_consistency(graph, voted, spot_count, min_island, true, true))
    if (ids.index_of(d.spot) < 0 && !ids.taken(d.row, d.col)) {
      decoded.push_back(d);
      ids.add(d, static_cast<int>(decoded.size()) - 1);
      added = true;
    }
  // (nothing added: `decoded` passed step 5 as it is, and hearing the links within a region as
  // wrong condemns no more)
  return added ? check_island_consistency(graph, std::move(decoded), spot_count, min_island, true, true) : decoded;
}

}  // namespace vision
