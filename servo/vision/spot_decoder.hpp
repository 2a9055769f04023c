// M-array decoding (paper §3.3), one function per step so each can be tested alone, one file
// per stage (decoder_support.hpp: what the stages share):
//   1. build_adjacency:            the closest spot in each of the four main  adjacency.cpp
//                                  directions
//   2. check_graph_consistency:    corner neighbours must agree (NW = W of N   adjacency.cpp
//                                  = N of W, ...); resolve_shear: a lattice   shear.cpp
//                                  sheared between two lines
//   3. read_windows:               each complete 8-neighbourhood looked up    window_reading.cpp
//                                  in the window table
//  3b. read_segments:              with the calibration, runs of 4 along a    window_reading.cpp
//                                  row or column, read along the epipolar
//                                  lines where no window reads
//   4. check_decoding_consistency: every window a spot takes part in must     consistency.cpp
//                                  name it the same
// and, beyond the paper:
//   5. check_island_consistency:   linked decoded spots must carry ids one    consistency.cpp
//                                  step apart
//   6. grow_lattice:               with the frame's epipolar geometry, ids    lattice_growth.cpp
//                                  given where the identified lattice
//                                  predicts them, links or none
//   7. name_edge_runs:             the foreshortened line beyond an           edge_runs.cpp
//                                  identified one (slivers at a silhouette),
//                                  named as a run
//  5b. restore_window_spots:       with the calibration, last: window-read    consistency.cpp
//                                  spots condemned by a link across a
//                                  silhouette within one region
// SpotDecoder runs them in order (spot_decoder.cpp), 5b after 7, on the blobs segment_spots
// finds (segmentation.cpp); given a white reference frame, on the pattern frame's ratio to it
// (normalise_by_white, then strengths_as_shown: reference.cpp).
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "servo/pattern/window_table.hpp"
#include "servo/vision/epipolar.hpp"
#include "servo/vision/reference.hpp"
#include "servo/vision/segmentation.hpp"
#include "servo/vision/spot.hpp"

namespace vision {

// What a smooth lattice cell is (steps 1, 2b and 3): on one smooth surface each row and column of a
// window bends little and each of its four cells is near a parallelogram; across a depth edge,
// with a spot from the surface behind shifted along its row, they are not (without the test the
// mended links let 10 wrong ids through on the ham).
struct CellShape {
  double bend = 0.4;         // how much a line's step may change from one spot to the next (of the step)
  double cell_slack = 0.35;  // how unlike a cell's opposite sides may be (of the step; step 7's runs too)
  // two steps along a line alike within this factor: step 2b's straight line, and step 1's
  // regular link (a link across a missing spot is twice as long as those continuing it)
  double step_ratio = 1.5;
};

// Step 1. The pattern's grid direction is estimated from the nearest-neighbour vectors (their
// angles modulo 90 deg); for each spot and each direction, the closest spot within +-40 deg of
// it is the candidate; only mutual links are kept (B east of A and A west of B).
// Step 1b (`mend`): two row chains one above the other are joined by the column offset most of
// their links take, and a missing link is completed where the neighbours' links say it lies.
// Step 1's numbers.
struct AdjacencyOptions {
  // rows: the closest spot within this angle (deg) of the pattern's east or west; columns, within
  // this of the perpendicular to the spot's own row (under perspective the columns shear away
  // from it, and a diagonal neighbour competes with the true one)
  double row_cone_deg = 35, column_cone_deg = 45;
  // candidates within this many times the spot's nearest-neighbour distance (at least half the
  // frame's spacing): a link may bridge a missing spot; the 3.5x reach was 30 % of the decode
  double reach = 3.5;
  // a column candidate's rank: distance x (1 + this x its angle to the perpendicular), so a
  // nearer diagonal neighbour does not beat the true one straight below
  double angle_weight = 2;
  // step 1b: two row chains are joined by the column offset at least this many of their links
  // take, and at least this share of them
  int chain_votes = 3;
  double chain_share = 0.75;
  // step 1b: a completed link's spot within this fraction of a step of where its neighbours'
  // links put it
  double completion_slack = 0.3;
};
AdjacencyGraph build_adjacency(const std::vector<Spot>& spots, bool mend = true, const AdjacencyOptions& options = {},
                               const CellShape& shape = {});

// Step 2. A corner neighbour is kept only when both paths to it exist and agree.
Neighbourhoods check_graph_consistency(const AdjacencyGraph& graph);

// A window read around a centre spot: the pattern position of that centre.
struct WindowReading {
  int centre = 0;               // spot index
  pattern::SpotId id;           // the centre's (row, col)
  bool corrected = false;       // read by the error-tolerant mode
  int wrong = -1;               // a corrected colour: the window cell (0..8) whose spot was misread;
                                // the reading does not vote for that spot
};

// The detected spots against the frame's epipolar geometry (see epipolar.hpp).
// EpipolarCheck::set_grown_limit's numbers: this many times the median residual of the
// window-read spots, at least the floor, the median taken from at least one window's spots (9;
// fewer: the tolerance alone; 3 named 9 ids more of 5.6 million on the calibrated tuning sweeps,
// so it is no number of its own). The dark ham went from 5 wrong ids in 100 poses to none, for
// 0.4 points.
struct GrownLimit {
  double times_median = 4.0;
  double floor_px = 1.0;
};
// That limit over a frame's residuals (pixels), at most `tolerance_px`.
double grown_limit_of(std::vector<double> residuals, const GrownLimit& limit, double tolerance_px);

struct EpipolarCheck {
  EpipolarCheck(const EpipolarGeometry& geometry, const std::vector<Spot>& spots);
  // spot `spot` may carry `id`
  bool confirms(int spot, const pattern::SpotId& id) const { return geometry.consistent(xy[spot], id); }
  // Steps 6 and 7 name a spot on weaker evidence than a window: there it must lie on its id's line
  // as closely as the frame's window-read spots lie on theirs. A blob of another surface that
  // sits where the lattice goes on passes the tolerance by chance, typically 1-3 px off, where
  // a frame's right ids lie a few tenths of a pixel off, and more with a calibration error,
  // which moves every spot alike: the limit is `limit.times_median` times the median residual of
  // the spots `decoded` names (at least `limit.floor_px`, at most the tolerance).
  void set_grown_limit(const std::vector<DecodedSpot>& decoded, const GrownLimit& limit = {});
  // (within the tolerance too, so that it implies confirms(): a step called before the limit is
  // set keeps the tolerance)
  bool confirms_grown(int spot, const pattern::SpotId& id) const {
    return geometry.residual_px(xy[spot], id) <= std::min(grown_limit_px, geometry.tolerance_px());
  }
  double grown_limit_px = std::numeric_limits<double>::infinity();
  // every spot of window `w` may carry the id the window's centre `centre` implies for it
  bool confirms(const Window& w, const pattern::SpotId& centre) const;

  const EpipolarGeometry& geometry;
  std::vector<Eigen::Vector2d> xy;  // normalised coordinates of every spot
};

// Step 2b, beyond the paper. A lattice seen under shear (a surface whose depth changes along
// the pattern's columns: the ham's flanks, the cylinder towards its silhouette) has its columns
// slanted by up to a whole step per row, and the north/south link of step 1 then goes to a
// diagonal neighbour. The lattices (row, column) and (row, column + row) are the same points:
// geometry cannot tell which is the pattern's, but the code can. For every spot whose window
// does not read, the rows above and below are tried shifted by -1, 0 and +1 along their row
// links (the column through the spot kept straight); when exactly one choice reads as a
// pattern window (and, with `check`, lies on its epipolar lines), the spot's north and south
// links are rewritten to it. Links are kept symmetric. Returns the graph with those links.
// A choice is taken when a row neighbour's column links are the same choice moved along the
// row: a shear slants a region, a window that reads by chance after a shift stands alone.
// Every window tried, and every window read afterwards, must be a smooth lattice cell: rows and
// columns that bend little and cells near parallelograms (a cell across a depth edge is not).
// kRows: the same with rows and columns exchanged (rows slanted against trusted columns: the
// cylinder towards its silhouette), run after the columns.
enum class ShearAxis { kColumns, kRows };
AdjacencyGraph resolve_shear(const std::vector<Spot>& spots, const AdjacencyGraph& graph, const Neighbourhoods& hoods,
                             const pattern::WindowTable& table, const EpipolarCheck* check = nullptr,
                             ShearAxis axis = ShearAxis::kColumns, const CellShape& shape = {});

struct ToleranceOptions {
  bool enabled = false;  // beyond the paper: accept a window with one missing neighbour or one
                         // wrong colour when exactly one pattern window fits it
  int max_missing = 1;   // neighbours a window may lack and still be completed
  // Issue 19: the decoder reads the pattern's minimum window distance d at load and, when
  // d >= 3, corrects one wrong colour and completes up to d - 1 = 2 missing neighbours: there
  // the one fitting window is the pattern's guarantee, not a guess (with the paper's d = 1
  // pattern, a misread window is often another valid one). false: only `enabled` decides.
  bool by_pattern_distance = true;
};

// Step 3. With an epipolar check, a reading is kept only when every spot of its window lies on
// the epipolar line of the id it implies, and an error-tolerant reading is kept when exactly one
// of the pattern windows within one symbol of it passes that check (a repair).
std::vector<WindowReading> read_windows(const std::vector<Spot>& spots, const Neighbourhoods& hoods,
                                        const pattern::WindowTable& table, const ToleranceOptions& tolerance = {},
                                        const EpipolarCheck* check = nullptr, const CellShape& shape = {});

// One reading's claim on one spot.
struct IdVote {
  int spot = 0;
  pattern::SpotId id;
  bool repaired = false;  // from a corrected or completed window
};
// What tells whether a window's code places each of its lines: the spots, their links, the pattern.
struct LineContext {
  const std::vector<Spot>& spots;
  const AdjacencyGraph& graph;
  const pattern::MArray& pattern;
};
// Whether line k (0-2 the window's rows, 3-5 its columns) of the window `w`, read as centred on
// `centre`, lies one step along itself: its colours are the pattern's one step over and the spot
// linked beyond one of its ends shows the shifted line's colour there (window_reading.cpp).
bool line_shifted(const LineContext& at, const Window& w, const pattern::SpotId& centre, int k);
// Each window reading votes for the id of its centre and of its 8 neighbours; a corrected one
// only for the four cells that share neither row nor column with its misread cell (votes_for);
// with `lines`, none for the cells of a line that line_shifted finds shifted.
void add_window_votes(const Neighbourhoods& hoods, const std::vector<WindowReading>& readings,
                      std::vector<IdVote>& votes, const LineContext* lines = nullptr);
bool votes_for(const WindowReading& r, int cell);

// Step 3b, beyond the paper, with the frame's epipolar geometry: a run of `length` spots
// linked along a row (east-west) or a column (north-south), each step close to the one before,
// is read as a 1 x length segment: the one place in the pattern with the run's colours along
// that axis and every spot within the tolerance of its id's epipolar line (a run that fits two
// places is dropped). Unlike a 3 x 3 window, a segment needs no links across the other axis: it
// reads the lines whose cross links are missing or sheared (a grazing face, a strip of the table
// past a silhouette, a cylinder's flank). What a window's other lines check, a run asks of its
// own: every spot within the frame's grown limit of its line (set from `by_windows`, the spots
// the windows named) and each alike the next along the run within `alike` (a spot named from one
// line neighbour, GrowthOptions::unlike); no spot named otherwise by a window, nor linked to a
// window-named spot whose id is not a step away. It votes for its spots but its two ends: a run
// that goes on past a silhouette onto the surface behind finds a spot there on the line of the
// id it predicts, with its colour one time in three. Any length from 3 (under 3: nothing read).
void read_segments(const std::vector<Spot>& spots, const AdjacencyGraph& graph, const EpipolarCheck& check,
                   const pattern::MArray& pattern, int length, const std::vector<DecodedSpot>& by_windows,
                   std::vector<IdVote>& votes, const CellShape& shape, double alike);

// Step 4. A spot is kept when all its votes agree (and it has at least `min_votes`, one of them
// exact), and no other spot has its id.
// `two_exact`: a spot with exactly two votes, both exact, is kept too.
std::vector<DecodedSpot> check_vote_consistency(const std::vector<Spot>& spots, const std::vector<IdVote>& votes,
                                                int min_votes, bool two_exact = false);
// Step 4 over window readings (the paper's step).
std::vector<DecodedSpot> check_decoding_consistency(const std::vector<Spot>& spots, const Neighbourhoods& hoods,
                                                    const std::vector<WindowReading>& readings, int min_votes,
                                                    const LineContext* lines = nullptr);

// Step 5, beyond the paper. Decoded spots linked in the adjacency graph must carry ids one
// step apart in the link's direction; a decoded spot contradicting a linked one is dropped,
// except where the link joins two regions of `min_island` or more id-consistent spots (two
// surfaces meeting at a depth edge, the link drawn across it: the link is what is wrong), or
// where its own region is that large and the other spot's is not (a misread spot or a small
// patch of another surface is what the link makes doubtful).
// Spots are then grouped into islands (linked, id-consistent); islands smaller than
// `min_island` are dropped: a misread region (a sheared grid read with the wrong columns, a
// window that happens to form a valid code) is a small island, a correctly read surface is not.
// `sheared_links`: a link whose ids are one step along it and one across also agrees (a
// column read obliquely); used with the epipolar check, whose readings need no such link.
// `within_region`: a link whose ends both lie in one such region is what is wrong too
// (restore_window_spots).
std::vector<DecodedSpot> check_island_consistency(const AdjacencyGraph& graph, std::vector<DecodedSpot> decoded,
                                                  int spot_count, int min_island, bool sheared_links = false,
                                                  bool within_region = false);

// Step 5b, with the calibration, after steps 6 and 7: the window-read spots (`voted`, step 4)
// that step 5 keeps when it hears a contradicting link within one region as the link's fault
// come back where their blob and id are still free, and the islands are checked again. Two
// surfaces that meet somewhere are one region (the egg's side runs into the table's lattice, a
// sheared link at a time); where a silhouette parts them the column links reach 2-3 rows down
// onto the table, and so do the grown lattice's links there: step 5, and its check after steps 6
// and 7, condemn both ends, though the window-read end is held by its windows, its agreeing
// links and its id's line. They come last, as no source of steps 6 and 7: grown from, they named
// the table's spot behind the dark egg's top (a blob of it merged with the egg's spot, on nearly
// the same epipolar line: 2 wrong ids more, at seed 11 drawn +-6 cm +-10 deg and in 12 egg
// sweeps of 3000 poses at seed 21 as wide; the egg's spills named nearly doubled). On the
// calibrated tuning sweeps +0.2-0.3 % of the ids, the egg up to 1.8 points, the same wrong ids
// (400 poses at seed 1; 1000 at seed 7, at seed 11 drawn +-6 cm +-10 deg, and the occluded
// cylinder's; the egg 3000 at seed 21, drawn as wide).
std::vector<DecodedSpot> restore_window_spots(const AdjacencyGraph& graph, const std::vector<DecodedSpot>& voted,
                                              std::vector<DecodedSpot> decoded, int spot_count, int min_island,
                                              const pattern::MArray& pattern);

// Step 6's numbers (the grown lattice), each set on the tuning scenes with what it did there.
struct GrowthOptions {
  // how far (fraction of a lattice step) a grown spot may be from where the lattice puts it:
  // wide, as the prediction may reach across a missing link
  // and the step changes fast on the oblique flanks. 0.45 (was 0.35): +0.4 points of the ham's
  // readable spots, +0.6 of the cylinder's, the same wrong ids in 24 sweeps of 1000 poses; 0.55
  // names fewer (a farther spot wins the place)
  double slack = 0.45;
  // A spot named from a single row or column neighbour (and corners), or one source short, must look
  // like its sources' mean: at least this fraction of their strength and of their area, at most its
  // inverse of their area. At a silhouette the prediction can fall on a speck or a faint wash blob.
  // Set on 1000-pose sweeps of the cylinder behind an occluder, the scenario that showed such wrong
  // ids. One number for the three bounds (the strength's and the area's floor were both 0.6; the
  // area's ceiling 1.7 for 1/0.6 named 19 ids fewer of 5.6 million on the calibrated tuning sweeps,
  // the same wrong ids; one source short, see below); a floor of 10 px on the area kept out no wrong
  // id (docs/decoding.md, "What each number does"). Any spot the lattice names with a smaller
  // area than this of its sources' mean is named but clipped (DecodedSpot::clipped), kept from
  // the law: held to it as a bound, every grown spot cost 0.29 % of the tuning sweeps' ids (and
  // the paper pattern's cylinder its lead over the decoder before issue 41); as a flag it costs
  // no id and kept the tuning sweeps' spills reaching the law from 689 to 101 (the box's clipped
  // spot), for 0.33 % of the right ids that reach it.
  double unlike = 0.6;
  // nor barely above the segmentation's threshold (mean chroma above it, 8-bit levels): the dim
  // glow at a silhouette, a spot of another row compressed there (1 wrong id in 1000 poses of
  // `cylinder_occlusion`'s widened draw); 0.2 % of the right ones are as faint. Step 7 asks it
  // too. Without it 0.7 % more of the readable spots are named on the tuning sweeps, but 3 wrong
  // ids more on the dark and the printed ham (1000 poses at +-6 cm, +-10 deg): it stays.
  float faintest = 5.0F;
  // One source fewer than asked names a spot when every source's step lands within this
  // fraction of a step of the blob (the prediction a quarter as loose as `slack`) and the blob
  // looks like its sources. At a silhouette only two identified spots may touch the next one (a
  // row or column neighbour and a corner); what fell at a depth edge within 0.2 of a step was
  // the surface behind's spot, never one within 0.12. +0.3 points of the ham's readable spots,
  // +0.5 of the cylinder's, the same wrong ids in 32 calibrated sweeps of 1000 poses.
  double tight_slack = 0.12;
  // Or when the row or column neighbour's step lands on the blob's line (within `tight_slack` of a
  // step aside: 0.08 of its own named 0.03 % fewer of the tuning sweeps' ids, the same wrong ids) at
  // 1/1.2-1.2 of its length (`on_line_stretch`), the corner's within `slack`: towards a silhouette
  // the surface turns away and the last step shrinks or stretches along itself (the ham's first and
  // last columns), and the corner's prediction, two steps, drifts by 0.2-0.4. Along a row the
  // epipolar line cannot tell a column from another, so the blob of the surface behind can lie on
  // the step's line: the one such wrong id seen (1000 cylinder poses) lay at 0.75 of the step, 0.45
  // as strong as its sources. A spot named one short looks like its sources as one named from a
  // single neighbour does (`unlike`; without that, no wrong id more on the tuning scenes, but one on
  // the held-out step under noise with the paper's pattern). +0.2 points of the ham's readable
  // spots, the same wrong ids in 32 calibrated sweeps. (Its own floor of 0.5 on the strength named
  // 0.05 % more of the tuning sweeps' ids than `unlike`, and 0.85 for the shortest step 244 fewer
  // of 5.6 million than 1/1.2, the same wrong ids: not worth a number each.) Step 7's candidate
  // lies at most this far along its source's step too.
  double on_line_stretch = 1.2;
  // a grown or run blob at least this fraction of its source's strength and area
  // (steps 6 and 7): a faint speck of noise, or the dim light of a surface behind an edge
  // (defocused, oblique), is not a spot of the source's surface. And a grown blob's area at
  // most its inverse (2.5) of the source's: a wider blob is the colour wash of a surface far out
  // of focus behind a silhouette (without the ceiling, the dark egg gave a wrong id in 1000
  // poses, seed 7, with either pattern): one number bounds both ways, as `unlike` does. A free
  // blob at least this fraction of a grown spot's strength on the line of the id it was given
  // could be that id's spot instead (nearest_free_blob): as bright as a grown spot may be.
  double alike = 0.4;
};

// Step 7's numbers (edge runs).
struct EdgeRunOptions {
  // where a run's candidate may lie from its source, along the source's step: the steps shrink
  // towards a silhouette (the surface turns away), so from 0.3 of a step, to as far as a last
  // step may stretch (GrowthOptions::on_line_stretch, 1.2: 1.15 of its own named 19 ids fewer
  // of 5.6 million on the calibrated tuning sweeps, the same wrong ids), and at most 0.3 of a
  // step aside (a cell's slack, 0.35, named a wrong id on the printed cylinder in 1000 poses,
  // seed 7)
  double nearest = 0.3, aside = 0.3;
  // consecutive candidates a run needs: each has the colour the pattern has there by chance one
  // time in three, so a run of 4 is one in 81 before the epipolar line and the positions (on
  // the calibrated tuning sweeps, 400 poses at seed 1: 3 named 0.11 % more and a wrong id, on
  // the coloured can with the paper's pattern; 5, 0.07 % fewer)
  int length = 4;
  // the candidate is looked for around the middle of that range along the source's step
  // (no number of its own: a fixed 0.7 names the same ids in the 72 tuning sweeps); a shortest
  // step of 2 px bounded nothing (the same ids without it)
  // a line beyond is foreshortened: its spots no larger than their sources (a larger blob there
  // is the wash of a surface behind, out of focus), and a run bridges one missing id at most
  double largest = 1.2;
  int gaps = 1;
};

// What step 6 made of a blob (DecodeResult::growth): named, or, from its last round of claims,
// why not. decode-sweep counts the readable spots it misses by these.
enum class GrowthOutcome : std::uint8_t {
  kUnclaimed = 0,   // no source's prediction landed on it
  kNamed,           // identified before step 6 or by it
  kUnlikeClaim,     // a prediction landed on it, but it is unlike the source (`alike`),
                    // cut by the image border, or off the claimed id's colour or line
  kDissent,         // two sources claim another id, or a third id is claimed
  kNoDirectSource,  // no row or column neighbour among its sources
  kFewSources,      // fewer than `min_sources` (and not one short on a tight prediction)
  kUnlikeSources,   // named from one row or column neighbour, or one short: unlike its sources
  kTaken,           // another spot has the claimed id
  kResidual,        // off the claimed id's line by more than the frame's grown limit
  kNeighbourFits,   // an id around the claimed one fits it too (and the lattice does not pin it)
  kNearerLine,      // another free id's line runs nearer it
  kNearerBlob,      // named, then withdrawn when growth ended: another free blob that could be
                    // the id's spot lies on its line too
};

// Step 6, beyond the paper. The lattice grown from the identified region where the graph has
// no link: from every identified spot, the lattice's steps (from identified neighbours) predict
// where each of the 8 ids around it lies; the spot found there (within 0.45 of a step) takes
// the id when `min_sources` identified spots predict it there (one of them a row or column
// neighbour), none predicts another id, and colour, epipolar line and uniqueness pass (no other
// spot has the id, no other id around fits the spot as well, no free id's line runs nearer it);
// once it has grown, a grown spot is withdrawn where another free blob that could be its id's
// spot lies on the id's line. The links the grown lattice found are added to `graph` where both
// ends had none.
// `outcomes` (optional): each spot's GrowthOutcome.
std::vector<DecodedSpot> grow_lattice(const std::vector<Spot>& spots, AdjacencyGraph& graph,
                                      const EpipolarCheck& check, const pattern::MArray& pattern,
                                      std::vector<DecodedSpot> decoded, int min_sources = 3,
                                      const GrowthOptions& options = {},
                                      std::vector<GrowthOutcome>* outcomes = nullptr);

// Step 7, beyond the paper. Runs along an edge: beyond an identified line of spots (a column
// before the cylinder's silhouette), the next line is foreshortened to slivers, closer than a
// step and a third of a spot's area, which step 6 refuses one at a time (a speck or the wash of
// the surface behind looks alike). Here they are taken as a run: from each identified spot, the
// blob ahead along its step (0.3 to 1.2 of it, 0.3 aside) with the pattern's colour there, on
// its epipolar line, not fainter than 0.4 of it; 4 or more such blobs for consecutive ids along
// the edge, each offset from the next as their sources are, are named. The spots named here
// are kept by the fragment test (`named_here`): their centroids are where their centres are
// (0.2-0.5 px on the cylinder), the sliver being the whole spot seen edge-on.
std::vector<DecodedSpot> name_edge_runs(const std::vector<Spot>& spots, AdjacencyGraph& graph,
                                        const EpipolarCheck& check, const pattern::MArray& pattern,
                                        std::vector<DecodedSpot> decoded, std::vector<char>* named_here = nullptr,
                                        const EdgeRunOptions& options = {}, const GrowthOptions& growth = {},
                                        const CellShape& shape = {});

// How the decoder uses a frame's epipolar geometry, when it is given one.
struct EpipolarOptions {
  // false: the decoder ignores the calibration (it still serves triangulation)
  bool enabled = true;
  double tolerance_px = 3.0;  // centroid error on curved surfaces is ~1 px; calibration adds to it
  // The epipolar lines of one frame often run along the pattern's rows: they tell the row, not
  // the column, so a window misread one column over still passes: DecoderOptions::min_votes
  // holds with the calibration too, and islands stay.
  // 3 (12 without the calibration: the epipolar line checks each id of an island): 5 named
  // +0.5 points of the ham's readable spots and +0.3 of the cylinder's against 12, and 3
  // +0.1-0.3 more on the ham and the compact objects (egg, can, wedge), no wrong id added in 132
  // calibrated tuning sweeps of 1000 poses (seed 7, seed 11 wide, both patterns)
  int min_island = 3;
  // Step 3b's runs: the spots a run reads (under 3: off, a run of 1 or 2 has no inner spot).
  // 4: a run votes for its 2 inner spots, and a spot no window voted for needs two runs' votes
  // (two exact votes, step 4): a line of k linked spots names its middle k - 4. On the
  // calibrated tuning sweeps (400 poses, seed 1, both patterns), against no runs: 3 +1.34 % of
  // the ids and the dark egg's wrong id back (a run of 3 fits two places often, and is dropped),
  // 4 +2.05 %, 5 +1.83, 6 +1.64, 7 +1.46, 9 +0.91 (and the dark egg's wrong id back); 4 on seed
  // 7, seed 11 +-6 cm +-10 deg, the occluded cylinder and the egg's 3000 wide poses: the same
  // wrong ids as 7, sweep for sweep. Read without its checks (each spot within the tolerance
  // only, every spot voted for) runs of 7 named 479 wrong ids, the ham's lower silhouette most
  // (docs/decoding.md, "Runs read along the epipolar lines").
  int segment_length = 4;
  // Without a calibration, decode a second time on the lines fitted to the first decoding's spots
  // (SpotDecoder::decode_uncalibrated). Off by default: the closed loop's figures in
  // docs/results.md are the decoder's without it; what it names, docs/decoding.md.
  bool fitted_lines = false;
  // Error-tolerant windows, confirmed epipolarly. Off: on the ham the confirmation still lets
  // wrong repairs through at depth edges (23 in 1000 poses), for 4 points of rate.
  bool tolerant = false;
  GrownLimit grown_limit;  // steps 6 and 7's epipolar residual limit
  bool grow = true;        // step 6
  bool edge_runs = true;   // step 7 (after step 6)
  GrowthOptions growth;
  EdgeRunOptions edge_run;
  // A spot with exactly two votes, both from exact windows (no repaired reading among its
  // votes), is named too, where `min_votes` asks for three: a spot next to a window cut by a
  // missing link, the image border or an edge has only two. With the epipolar check: +1.0 points of the cylinder's readable spots, +1.7 with the paper's pattern,
  // no wrong id added in 24 sweeps (docs/decoding.md).
  bool two_exact_votes = true;
  // identified spots around a blob (row, column or corner neighbours) that must predict the same
  // id for step 6 to name it: at an object's edge the spot beyond (on the surface behind) can sit where the lattice goes on,
  // on the same epipolar line, so one source is not enough. Three: a spot beyond a decoded edge
  // has its linked source and two corners; two let 17 wrong ids through in 1000 ham poses
  // (a spot's sliver cut by the ham's silhouette), three none
  int min_sources = 3;
};

struct DecoderOptions {
  SegmentationOptions segmentation;
  ToleranceOptions tolerance;
  // Windows that must name a spot. The paper keeps a spot when all its windows agree, even
  // if there is only one; a single misread window (a wrong link or colour that happens to
  // form a valid code: 324 of the 19683 codes are) then yields up to 9 wrong ids. Measured
  // over 300 random ham poses, 2 votes still let 6 wrong ids through, 3 let none
  // (docs/decoding.md); the cost is the pattern's corners and their neighbours.
  int min_votes = 3;
  int min_island = 12;  // step 5; 0 turns it off (the paper's decoder)
  // steps 1b (row chains align the columns, links completed from the lattice) and 2b (shear
  // resolved by the code); false: the links as the nearest-spot rule makes them (issue 18's decoder)
  bool mend_links = true;
  AdjacencyOptions adjacency;
  // a blob smaller than this fraction of the median area of the spots linked to it is a fragment
  // (a spot cut by an edge: its centroid is not its centre) and is not reported, unless an edge
  // run named it
  double fragment_area = 0.5;
  // Nor is a speck: a blob under this fraction of the median area of the spots identified around
  // its id, wherever its links go (the fragment test's linked spots can be specks too). A far
  // wall's wash speck of the right colour where the ham's next row would lie was named by the
  // row's windows (5 px against their 60-100: 4 wrong ids in 3000 uncalibrated ham poses, each
  // the same place). Under 0.2 on the 72 tuning sweeps of 1000 poses: of the right ids 0 on
  // the ham, at most 11 of 120 000 on the cylinder; 3-23 % of the ham's spills; 3 of the 4
  // wrong ids (the fourth remains).
  double speck_area = 0.2;
  CellShape cell_shape;
  EpipolarOptions epipolar;  // used when decode() is given the frame's geometry
  ReferenceOptions reference;  // used when decode() is given a white reference frame
};

// Without the calibration (the closed loop decodes so unless told `--projector`): the reported
// spots off the lines of the frame's own epipolar geometry, fitted to them (FittedEpipolarLines),
// marked off_line as with the calibration: beyond the grown limit of their residuals
// (`options.grown_limit`, at most `options.tolerance_px`); every other spot unmarked. Nothing is
// marked where fewer than 9 spots (one window's) are named.
void mark_off_fitted_lines(std::vector<DecodedSpot>& decoded, const calibration::CameraIntrinsics& camera,
                           const EpipolarOptions& options);

struct DecodeResult {
  std::vector<Spot> detected;
  std::vector<DecodedSpot> decoded;
  // the links the windows were read on (steps 1, 2 and 2b), to see where decoding lost a spot
  AdjacencyGraph graph;
  Neighbourhoods hoods;
  int readings = 0;  // windows read (step 3)
  // step 6's outcome for each detected spot (empty when step 6 did not run: no calibration)
  std::vector<GrowthOutcome> growth;
  int rejected_blobs = 0;
};

// The buffers decoding reuses from frame to frame (room only: no result carries over from one
// frame to the next). A caller that decodes many frames keeps one per thread and passes it;
// without one, each decoding makes its own.
struct DecodeScratch {
  SegmentationScratch segmentation;
  cv::Mat ratio, white_mean;  // the pattern frame over the white one, and the white one's 3 x 3 mean
};

// Decoding holds no state of its own: one decoder serves any number of threads, each with its
// own DecodeScratch.
class SpotDecoder {
 public:
  SpotDecoder(pattern::WindowTable table, DecoderOptions options = {});
  // Throws std::invalid_argument for an empty or non-RGB8 image (see segment_spots).
  // `geometry` (optional): the frame's camera-projector geometry, for the epipolar steps; with
  // it the segmentation's chroma levels follow the camera's crosstalk (SegmentationOptions).
  // Throws std::invalid_argument when its grid of spots is not the pattern's.
  // `scratch` (optional): room reused from the caller's last frame.
  DecodeResult decode(const cv::Mat& rgb, const EpipolarGeometry* geometry = nullptr,
                      DecodeScratch* scratch = nullptr) const;
  // With the white reference frame taken at the same pose (reference.hpp): the blobs are
  // segmented on the pattern frame's ratio to it, the surface's albedo divided out, and keep the
  // strength the pattern frame shows (strengths_as_shown). Throws std::invalid_argument when the
  // two frames' sizes differ or either is not RGB8.
  DecodeResult decode(const cv::Mat& rgb, const cv::Mat& white, const EpipolarGeometry* geometry = nullptr,
                      DecodeScratch* scratch = nullptr) const;
  DecodeResult decode_spots(std::vector<Spot> spots, const EpipolarGeometry* geometry = nullptr) const;
  // Without the projector's calibration, knowing the camera's intrinsics: decode() without a
  // geometry, then either the spots off the frame's own fitted lines marked (mark_off_fitted_lines)
  // or, with `EpipolarOptions::fitted_lines`, the same blobs decoded again on those lines, fitted
  // with rank 2 (EpipolarGeometry from FittedEpipolarLines): steps 3b, 5b, 6 and 7 as with a
  // calibration, each spot off its line marked. Where no lines can be fitted (under 9 spots
  // named), the first decoding, marked.
  DecodeResult decode_uncalibrated(const cv::Mat& rgb, const calibration::CameraIntrinsics& camera,
                                   DecodeScratch* scratch = nullptr) const;
  // the same with a white reference frame (decode's above); an empty `white`: none
  DecodeResult decode_uncalibrated(const cv::Mat& rgb, const cv::Mat& white, const calibration::CameraIntrinsics& camera,
                                   DecodeScratch* scratch = nullptr) const;
  const DecoderOptions& options() const { return options_; }
  const pattern::WindowTable& table() const { return table_; }
  // the pattern's minimum window distance, read at construction
  int pattern_distance() const { return distance_; }

 private:
  // the frame's blobs, the chroma levels following the camera's crosstalk when `calibrated`;
  // with a white frame (not empty), segmented on the ratio
  Segmentation segment(const cv::Mat& rgb, const cv::Mat& white, bool calibrated, DecodeScratch* scratch) const;
  pattern::WindowTable table_;
  DecoderOptions options_;
  int distance_ = 1;
};

}  // namespace vision
