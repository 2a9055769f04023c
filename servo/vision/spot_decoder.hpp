// M-array decoding (paper §3.3), one function per step so each can be tested alone:
//   1. build_adjacency:            the closest spot in each of the four main directions
//   2. check_graph_consistency:    corner neighbours must agree (NW = W of N = N of W, ...)
//   3. read_windows:               each complete 8-neighbourhood looked up in the window table
//   4. check_decoding_consistency: every window a spot takes part in must name it the same
// SpotDecoder runs them in order.
#pragma once

#include <optional>
#include <vector>

#include "servo/pattern/window_table.hpp"
#include "servo/vision/segmentation.hpp"
#include "servo/vision/spot.hpp"

namespace vision {

// Step 1. The pattern's grid direction is estimated from the nearest-neighbour vectors (their
// angles modulo 90 deg); for each spot and each direction, the closest spot within +-40 deg of
// it is the candidate; only mutual links are kept (B east of A and A west of B).
AdjacencyGraph build_adjacency(const std::vector<Spot>& spots);

// Step 2. A corner neighbour is kept only when both paths to it exist and agree.
Neighbourhoods check_graph_consistency(const AdjacencyGraph& graph);

// A window read around a centre spot: the pattern position of that centre.
struct WindowReading {
  int centre = 0;               // spot index
  pattern::SpotId id;           // the centre's (row, col)
  bool corrected = false;       // read by the error-tolerant mode
};

struct ToleranceOptions {
  bool enabled = false;  // beyond the paper: accept a window with one missing neighbour or one
                         // wrong colour when exactly one pattern window fits it
};

// Step 3.
std::vector<WindowReading> read_windows(const std::vector<Spot>& spots, const Neighbourhoods& hoods,
                                        const pattern::WindowTable& table, const ToleranceOptions& tolerance = {});

// Step 4. Each reading votes for the id of its centre and of its 8 neighbours; a spot is kept
// when all its votes agree (and it has at least `min_votes`), and no other spot has its id.
std::vector<DecodedSpot> check_decoding_consistency(const std::vector<Spot>& spots, const Neighbourhoods& hoods,
                                                    const std::vector<WindowReading>& readings, int min_votes);

// Step 5, beyond the paper. Decoded spots linked in the adjacency graph must carry ids one
// step apart in the link's direction; a decoded spot contradicting a linked one is dropped.
// Spots are then grouped into islands (linked, id-consistent); islands smaller than
// `min_island` are dropped: a misread region (a sheared grid read with the wrong columns, a
// window that happens to form a valid code) is a small island, a correctly read surface is not.
std::vector<DecodedSpot> check_island_consistency(const AdjacencyGraph& graph, std::vector<DecodedSpot> decoded,
                                                  int spot_count, int min_island);

struct DecoderOptions {
  SegmentationParams segmentation;
  ToleranceOptions tolerance;
  // Windows that must name a spot. The paper keeps a spot when all its windows agree, even
  // if there is only one; a single misread window (a wrong link or colour that happens to
  // form a valid code: 324 of the 19683 codes are) then yields up to 9 wrong ids. Measured
  // over 300 random ham poses, 2 votes still let 6 wrong ids through, 3 let none
  // (docs/decoding.md); the cost is the pattern's corners and their neighbours.
  int min_votes = 3;
  int min_island = 12;  // step 5; 0 turns it off (the paper's decoder)
};

struct DecodeResult {
  std::vector<Spot> detected;
  std::vector<DecodedSpot> decoded;
  int readings = 0;  // windows read (step 3)
  int rejected_blobs = 0;
};

// Not for concurrent use: decode() reuses per-frame buffers (one decoder per thread).
class SpotDecoder {
 public:
  SpotDecoder(pattern::WindowTable table, DecoderOptions options = {});
  // Throws std::invalid_argument for an empty or non-RGB8 image (see segment_spots).
  DecodeResult decode(const cv::Mat& rgb) const;
  DecodeResult decode_spots(std::vector<Spot> spots) const;
  const pattern::WindowTable& table() const { return table_; }

 private:
  pattern::WindowTable table_;
  DecoderOptions options_;
  mutable SegmentationScratch scratch_;
};

}  // namespace vision
